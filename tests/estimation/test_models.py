"""Model Jacobians vs central finite differences, and the discretised Q vs Van Loan (lti_disc)."""

import numpy as np
import pytest
from scipy.linalg import expm

from vtrack.estimation.models import (
    Bearings,
    ConstantAcceleration,
    Ranges,
    Unicycle,
    WienerVelocity,
)

SENSORS = np.array([[1.0, -2.0], [1.0, 2.0], [1.0 - 2.0 * np.sqrt(3.0), 0.0]])


def _fd_jacobian(fun, x, eps=1e-6, residual=None):
    """Central differences, column j = (f(x + e_j) - f(x - e_j)) / 2 eps (wrapped if angular)."""
    cols = []
    for j in range(len(x)):
        e = np.zeros_like(x)
        e[j] = eps
        d = fun(x + e) - fun(x - e) if residual is None else residual(fun(x + e), fun(x - e))
        cols.append(d / (2 * eps))
    return np.stack(cols, axis=-1)


def _states(n, count=50, seed=0):
    """Random states in all four quadrants around the sensors, plus points right next to the
    bearing branch cut (target due -x of a sensor, where atan2 jumps from pi to -pi)."""
    rng = np.random.default_rng(seed)
    xs = list(rng.uniform(-5, 5, (count, n)))
    for sx, sy in SENSORS:
        x = rng.normal(size=n)
        x[0], x[1] = sx - 1.5, sy + 1e-9  # on the cut of this sensor
        xs.append(x)
    return xs


@pytest.mark.parametrize("n", [3, 4, 6])
def test_bearing_jacobian_matches_finite_differences(n):
    model = Bearings(SENSORS, 0.05, n=n)
    for x in _states(n):
        J = model.H(x)
        assert J.shape == (3, n)
        # wrapped differences: the numerical derivative is fine across the +-pi cut
        np.testing.assert_allclose(J, _fd_jacobian(model.h, x, residual=model.residual),
                                   rtol=1e-6, atol=1e-8)
    # the sign seed 000 eq. 8 gets wrong: d/dy of atan2(y - sy, x - sx) is +(x - sx)/r^2
    x = np.array([3.0, 0.0, 0.0, 0.0][:n] + [0.0] * (n - 4))
    assert Bearings([[0.0, 0.0]], 0.05, n=n).H(x)[0, 1] == pytest.approx(1.0 / 3.0)


@pytest.mark.parametrize("n", [3, 4, 6])
def test_range_jacobian_matches_finite_differences(n):
    model = Ranges(SENSORS, 1.0, n=n)
    for x in _states(n, seed=1):
        np.testing.assert_allclose(model.H(x), _fd_jacobian(model.h, x), rtol=1e-6, atol=1e-8)


def test_unicycle_jacobian_matches_finite_differences():
    model = Unicycle(q=[1e-6, 1e-6, 1e-4])
    rng = np.random.default_rng(2)
    for _ in range(50):
        x = rng.uniform(-4, 4, 3)
        u = np.array([rng.uniform(-2, 2), rng.uniform(-1, 1)])
        dt = rng.uniform(0.01, 1.0)
        F = model.F(x, dt, u)
        fd = _fd_jacobian(lambda s: model.f(s, dt, u), x, residual=model.residual)
        np.testing.assert_allclose(F, fd, rtol=1e-6, atol=1e-8)
    # the stacked (sigma-point) path of f agrees with the single-state path
    X = rng.normal(size=(7, 3))
    u = np.array([0.5, 0.2])
    np.testing.assert_allclose(model.f(X, 0.1, u), np.array([model.f(x, 0.1, u) for x in X]))


@pytest.mark.parametrize("model_cls,order", [(WienerVelocity, 2), (ConstantAcceleration, 3)])
@pytest.mark.parametrize("dt", [0.01, 0.04, 1.0])
def test_discrete_Q_matches_van_loan(model_cls, order, dt):
    """Q(dt) = int_0^dt e^{A s} L q L' e^{A' s} ds via Van Loan's matrix exponential (what the
    toolbox's lti_disc computes), for a chain of `order` integrators per axis, 2 axes."""
    q = 0.1
    model = model_cls(q)
    n = 2 * order
    A_axis = np.diag(np.ones(order - 1), 1)
    L_axis = np.zeros((order, 1))
    L_axis[-1, 0] = 1.0
    A = np.kron(A_axis, np.eye(2))
    L = np.kron(L_axis, np.eye(2))
    M = np.block([[A, L @ (q * np.eye(2)) @ L.T], [np.zeros((n, n)), -A.T]])
    E = expm(M * dt)
    Phi = E[:n, :n]
    Q = E[:n, n:] @ Phi.T
    np.testing.assert_allclose(model.transition(dt), Phi, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(model.Q(dt), 0.5 * (Q + Q.T), rtol=1e-9, atol=1e-18)


@pytest.mark.parametrize("a", [0.0, 1.0, (np.pi / 2) / 51 / 0.01, -30.0])
def test_closed_form_turn_equals_expm(a):
    """The tests' (and examples/make_bearings_csv.py's) closed-form coordinated turn is the
    toolbox's expm(Fc dt)."""
    import runpy
    from pathlib import Path

    import seed000 as S

    np.testing.assert_allclose(S.turn_transition(a, 0.01), S.turn_transition_expm(a, 0.01),
                               rtol=0, atol=1e-13)
    example = Path(__file__).resolve().parents[2] / "examples" / "make_bearings_csv.py"
    ns = runpy.run_path(str(example))
    np.testing.assert_allclose(ns["turn_transition"](a, 0.01), S.turn_transition_expm(a, 0.01),
                               rtol=0, atol=1e-13)
