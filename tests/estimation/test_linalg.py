"""Numerical building blocks: wrap_angle, cholupdate/downdate, tria, the Joseph-form update."""

import numpy as np
import pytest

from vtrack.estimation.kalman import kf_update
from vtrack.estimation.linalg import (DowndateError, cholesky_each, cholupdate, tria,
                                     wrap_angle)
from vtrack.estimation.models import WienerVelocity

PI = np.pi


# ------------------------------------------------------------------------ wrap_angle


def test_wrap_angle_edges_map_to_plus_pi():
    assert wrap_angle(PI) == PI
    assert wrap_angle(-PI) == PI
    assert wrap_angle(3 * PI) == PI
    assert wrap_angle(-3 * PI) == PI
    # Just above pi, (pi - a) mod 2pi rounds up to exactly 2pi; the result must still be in
    # (-pi, pi] (it used to come out as -pi).
    assert wrap_angle(np.nextafter(PI, 4.0)) == PI
    assert wrap_angle(0.0) == 0.0


def test_wrap_angle_range_and_round_trip():
    rng = np.random.default_rng(0)
    a = np.concatenate([rng.uniform(-100, 100, 200_000),
                        PI + rng.uniform(-1e-14, 1e-14, 10_000),
                        -PI + rng.uniform(-1e-14, 1e-14, 10_000),
                        np.arange(-20, 21) * PI])
    w = wrap_angle(a)
    assert np.all(w > -PI) and np.all(w <= PI)
    # same angle: the difference is a multiple of 2 pi
    turns = (a - w) / (2 * PI)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-12)
    # idempotent (up to one ulp of pi from the two subtractions), and identity inside the range
    np.testing.assert_allclose(wrap_angle(w), w, rtol=0, atol=1e-15)
    inside = rng.uniform(-PI, PI, 1000)
    np.testing.assert_allclose(wrap_angle(inside), inside, rtol=0, atol=1e-15)
    # works elementwise on any shape and keeps it
    assert wrap_angle(a[:220_000].reshape(-1, 40)).shape == (5500, 40)


# ----------------------------------------------------------------- cholupdate and tria


def _random_spd(rng, n, cond=1e3):
    U, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (U * np.geomspace(1.0, cond, n)) @ U.T


@pytest.mark.parametrize("n", [1, 2, 4, 7])
def test_cholupdate_update_matches_cholesky(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        P = _random_spd(rng, n)
        v = rng.normal(size=n)
        L1 = cholupdate(np.linalg.cholesky(P), v, +1.0)
        np.testing.assert_allclose(L1, np.linalg.cholesky(P + np.outer(v, v)),
                                   rtol=1e-10, atol=1e-12)
        assert np.allclose(np.triu(L1, 1), 0.0)


@pytest.mark.parametrize("n", [1, 2, 4, 7])
def test_cholupdate_downdate_matches_cholesky(n):
    rng = np.random.default_rng(10 + n)
    for _ in range(20):
        P = _random_spd(rng, n)
        # a downdate that stays PD: v = 0.9 * (a unit-Mahalanobis direction)
        w = rng.normal(size=n)
        v = 0.9 * np.linalg.cholesky(P) @ (w / np.linalg.norm(w))
        L1 = cholupdate(np.linalg.cholesky(P), v, -1.0)
        np.testing.assert_allclose(L1, np.linalg.cholesky(P - np.outer(v, v)),
                                   rtol=1e-8, atol=1e-10)


def test_failing_downdate_raises():
    rng = np.random.default_rng(5)
    P = _random_spd(rng, 4)
    w = rng.normal(size=4)
    v = 1.1 * np.linalg.cholesky(P) @ (w / np.linalg.norm(w))  # P - v v' is indefinite
    assert np.linalg.eigvalsh(P - np.outer(v, v)).min() < 0
    with pytest.raises(DowndateError):
        cholupdate(np.linalg.cholesky(P), v, -1.0)
    with pytest.raises(DowndateError):  # the simplest case: 1 - 2^2 < 0
        cholupdate(np.eye(1), np.array([2.0]), -1.0)


@pytest.mark.parametrize("n,cols", [(1, 1), (3, 3), (4, 9), (4, 12), (6, 19)])
def test_tria_gives_lower_factor_of_MMt(n, cols):
    rng = np.random.default_rng(n * 100 + cols)
    M = rng.normal(size=(n, cols))
    S = tria(M)
    assert S.shape == (n, n)
    assert np.allclose(np.triu(S, 1), 0.0)
    assert np.all(np.diag(S) >= 0)
    np.testing.assert_allclose(S @ S.T, M @ M.T, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(S, np.linalg.cholesky(M @ M.T), rtol=1e-9, atol=1e-12)


# ---------------------------------------------------------------------- Joseph form


def test_joseph_update_keeps_P_symmetric_psd_with_suboptimal_gain():
    """10^4 updates: 100 chained predict + kf_update steps of a batch of 100 independent
    filters (kf_update takes the batch in one call). Each filter is given a deliberately
    wrong, far too small R (1e-12..1e-6 while the innovations are O(1)), so the gain is
    suboptimal and P is driven towards singularity in the measured directions.

    Claim: the Joseph form (plus re-symmetrisation) keeps every posterior P exactly symmetric
    and PSD (smallest eigenvalue >= -1e-12 * largest), and it is the Joseph expression for
    the gain used. Control, to show the scenario has teeth: the short form P = (I - K H) P
    run on the same sequence loses PSD in a large share of the updates.
    """
    rng = np.random.default_rng(0)
    n, m, batch, steps = 4, 2, 100, 100
    T = lambda a: np.swapaxes(a, -1, -2)  # noqa: E731
    motion = WienerVelocity(q=1e-6)
    F, Q = motion.transition(0.01), motion.Q(0.01)
    P = np.broadcast_to(np.diag([1e4, 1e4, 1e4, 1e4]), (batch, n, n)).copy()
    P_short = P.copy()
    short_indefinite = 0
    for _ in range(steps):
        H = np.concatenate([rng.normal(size=(batch, m, 2)), np.zeros((batch, m, 2))], axis=2)
        R_wrong = np.eye(m) * 10.0 ** rng.uniform(-12, -6, (batch, 1, 1))
        nu = rng.normal(size=(batch, m))
        _, P_post, info = kf_update(np.zeros((batch, n)), P, nu, H, R_wrong)
        np.testing.assert_array_equal(P_post, T(P_post))
        ev = np.linalg.eigvalsh(P_post)
        assert np.all(ev[:, 0] >= -1e-12 * ev[:, -1])
        A = np.eye(n) - info.K @ H
        joseph = A @ P @ T(A) + info.K @ R_wrong @ T(info.K)
        assert np.all(np.abs(P_post - joseph) <= 1e-6 * np.abs(joseph) + 1e-9 * ev[:, -1:, None])
        # control: the short form on the same sequence
        S = H @ P_short @ T(H) + R_wrong
        K = T(np.linalg.solve(S, H @ P_short))
        P_short = (np.eye(n) - K @ H) @ P_short
        ev_s = np.linalg.eigvalsh(0.5 * (P_short + T(P_short)))
        short_indefinite += int(np.sum(ev_s[:, 0] < -1e-12 * np.abs(ev_s).max(axis=1)))
        P = F @ P_post @ F.T + Q
        P_short = F @ P_short @ F.T + Q
    assert short_indefinite > 1000


# ------------------------------------------------------------------------ cholesky_each


def test_cholesky_each_flags_the_matrices_that_are_not_positive_definite():
    """Per matrix: np.linalg.cholesky's factor where it is positive definite (the same
    LAPACK call, so bit for bit on one machine), NaN and False where it is not; numpy's own
    call raises for the whole stack."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(7, 4, 4))
    P = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(4)
    P[2] -= 30.0 * np.eye(4)                       # negative definite
    P[5, 3, 3] = -1e-3 + P[5, 3, :3] @ np.linalg.solve(P[5, :3, :3], P[5, :3, 3])  # indefinite
    L, ok = cholesky_each(P)
    assert ok.tolist() == [True, True, False, True, True, False, True]
    for i in np.flatnonzero(ok):
        np.testing.assert_allclose(L[i], np.linalg.cholesky(P[i]), rtol=1e-15, atol=0)
    assert np.isnan(L[~ok]).all()
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(P)
