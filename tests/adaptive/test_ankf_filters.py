"""ANKF1 / ANKF2 (vtrack.adaptive.ankf; SEEDS 2.4): window behaviour, the R floor, the
fading-factor clips, missing cells and option validation."""

import numpy as np
import pytest

from vtrack.adaptive.ankf import (
    FadingAdaptiveEKF,
    InnovationAdaptiveEKF,
    fading_factors,
    iae_measurement_noise,
    scale_noise,
)
from vtrack.adaptive.innovation_windows import InnovationCovarianceWindow
from vtrack.estimation.kalman import kf_update
from vtrack.estimation.models import Bearings, WienerVelocity, position_measurement
from vtrack.filter_kinds import FILTER_KINDS, make_filter

DT = 0.01
SENSORS = np.array([[1.0, -2.0], [1.0, 2.0]])
X0 = np.array([0.0, 0.0, 1.0, 0.0])
P0 = np.diag([0.1, 0.1, 10.0, 10.0])


def _bearing_data(steps, sigma=0.05, seed=1):
    rng = np.random.default_rng(seed)
    motion = WienerVelocity(0.1)
    meas = Bearings(SENSORS, 0.05)
    F = motion.transition(DT)
    x = X0.copy()
    zs = []
    for _ in range(steps):
        x = F @ x
        zs.append(meas.h(x) + sigma * rng.standard_normal(2))
    return motion, meas, np.array(zs)


def _run(kind, zs, motion, meas, **opts):
    f = make_filter(kind, motion, meas, np.zeros(4), P0, **opts)
    xs, Ps = [], []
    for z in zs:
        f.step(DT, z)
        xs.append(f.x.copy())
        Ps.append(f.P.copy())
    return f, np.array(xs), np.array(Ps)


def test_kinds_are_registered_with_their_options():
    make_filter("ekf", WienerVelocity(0.1), Bearings(SENSORS, 0.05), X0, P0)  # imports them
    assert set(FILTER_KINDS["ankf1"][1]) == {"window", "r_floor", "adapt_r", "adapt_q"}
    assert set(FILTER_KINDS["ankf2"][1]) == {"window", "lambda_max", "ratio_min", "ratio_max",
                                             "multiple_factors", "fade_prior"}
    f1 = make_filter("ankf1", WienerVelocity(0.1), Bearings(SENSORS, 0.05), X0, P0, window=5,
                     r_floor=0.1, adapt_q=True, adapt_r=False)
    f2 = make_filter("ankf2", WienerVelocity(0.1), Bearings(SENSORS, 0.05), X0, P0,
                     window=7.0, lambda_max=2, multiple_factors=True)
    assert isinstance(f1, InnovationAdaptiveEKF) and f1.kind == "ankf1"
    assert f1.window.size == 5 and f1.adapt_q and not f1.adapt_r
    assert isinstance(f2, FadingAdaptiveEKF) and f2.kind == "ankf2"
    assert f2.window.size == 7 and f2.lambda_max == 2.0 and f2.multiple_factors


@pytest.mark.parametrize("kind,opts,msg", [
    ("ankf1", {"lambda_max": 2.0}, "does not take"),       # an ANKF2 option
    ("ankf2", {"r_floor": 0.1}, "does not take"),          # an ANKF1 option
    ("ankf1", {"alpha": 1.0}, "does not take"),
    ("ankf1", {"window": 0}, "window"),
    ("ankf1", {"window": 2.5}, "window"),
    ("ankf2", {"window": True}, "window"),
    ("ankf1", {"r_floor": 0.0}, "r_floor"),
    ("ankf1", {"r_floor": float("nan")}, "r_floor"),
    ("ankf1", {"adapt_q": "yes"}, "adapt_q"),
    ("ankf2", {"lambda_max": 0.5}, "lambda_max"),
    ("ankf2", {"ratio_min": 0.0}, "ratio_min"),
    ("ankf2", {"ratio_min": 2.0, "ratio_max": 1.0}, "ratio_max"),
    ("ankf2", {"fade_prior": 3}, "fade_prior"),
])
def test_bad_options_are_rejected(kind, opts, msg):
    with pytest.raises(ValueError, match=msg):
        make_filter(kind, WienerVelocity(0.1), Bearings(SENSORS, 0.05), X0, P0, **opts)


def test_window_is_a_ring_buffer():
    w = InnovationCovarianceWindow(3, 2)
    rng = np.random.default_rng(0)
    nus = rng.standard_normal((7, 2))
    for i, nu in enumerate(nus):
        assert w.full == (i >= 3)
        if not w.full:
            with pytest.raises(ValueError):
                w.covariance()
        w.push(nu)
    last = nus[-3:]
    np.testing.assert_allclose(w.covariance(), last.T @ last / 3, atol=1e-15)
    assert w.count == 7


def test_window_works_on_stacks():
    w = InnovationCovarianceWindow(4, (5, 2))
    rng = np.random.default_rng(1)
    nus = rng.standard_normal((6, 5, 2))
    for nu in nus:
        w.push(nu)
    expected = np.einsum("kri,krj->rij", nus[-4:], nus[-4:]) / 4
    np.testing.assert_allclose(w.covariance(), expected, atol=1e-15)


@pytest.mark.parametrize("kind", ["ankf1", "ankf2"])
@pytest.mark.parametrize("window", [1, 5, 20])
def test_plain_ekf_until_the_window_is_full(kind, window):
    motion, meas, zs = _bearing_data(60, sigma=0.2)     # R mis-specified: adaptation acts
    _, x_ekf, P_ekf = _run("ekf", zs, motion, meas)
    f, x, P = _run(kind, zs, motion, meas, window=window)
    # the first window-1 updates are the EKF's (the N-th innovation completes the window)
    np.testing.assert_allclose(x[: window - 1], x_ekf[: window - 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(P[: window - 1], P_ekf[: window - 1], rtol=0, atol=1e-12)
    assert np.max(np.abs(x[window - 1:] - x_ekf[window - 1:])) > 1e-6
    assert f.window.count == 60


def test_ankf1_r_is_the_iae_estimate_when_above_the_floor():
    motion, meas, zs = _bearing_data(40, sigma=0.3)
    f = make_filter("ankf1", motion, meas, np.zeros(4), P0, window=10)
    nus = []
    for z in zs:
        f.predict(DT)
        H = meas.H(f.x)
        nus.append(meas.residual(z, meas.h(f.x)))
        HPH = H @ f.P @ H.T
        f.update(z)
    C_hat = np.array(nus[-10:]).T @ np.array(nus[-10:]) / 10
    expected = np.maximum(np.diag(C_hat - HPH), 0.01 * np.diag(meas.R))
    np.testing.assert_allclose(f.R_hat, expected, rtol=1e-12)
    np.testing.assert_allclose(f.R_used, np.diag(expected), rtol=1e-12)
    assert np.all(f.R_hat > 0.01 * np.diag(meas.R))    # sigma 0.3 vs nominal 0.05


@pytest.mark.parametrize("r_floor", [0.01, 0.5])
def test_ankf1_r_floor(r_floor):
    """Innovations of zero (z = h(x-) exactly) would give R_hat <= 0: it is floored."""
    motion = WienerVelocity(0.1)
    meas = position_measurement(4, sigma=[0.3, 0.4])
    f = make_filter("ankf1", motion, meas, X0, P0, window=4, r_floor=r_floor)
    for _ in range(6):
        f.predict(DT)
        f.update(meas.h(f.x))
    np.testing.assert_allclose(f.R_hat, r_floor * np.array([0.09, 0.16]), rtol=1e-12)
    np.testing.assert_allclose(np.diag(f.R_used), f.R_hat)
    assert np.all(np.linalg.eigvalsh(f.P) > 0)


def test_iae_floor_function():
    C_hat = np.array([[0.01, 0.0], [0.0, 0.5]])
    HPH = np.array([[0.02, 0.0], [0.0, 0.1]])
    R = np.diag([0.0025, 0.0025])
    np.testing.assert_allclose(iae_measurement_noise(C_hat, HPH, R, 0.01), [2.5e-5, 0.4])


def test_fading_factor_clips():
    C = np.diag([1.0, 1.0])
    lam_P, lam_R = fading_factors(1000.0 * C, C, 1.5, 0.01, 100.0)
    assert lam_P == 1.5 and np.all(lam_R == 100.0)
    lam_P, lam_R = fading_factors(1e-6 * C, C, 1.5, 0.01, 100.0)
    assert lam_P == 1.0 and np.all(lam_R == 0.01)
    lam_P, lam_R = fading_factors(1.2 * C, C, 1.5, 0.01, 100.0)
    assert lam_P == pytest.approx(1.2) and np.allclose(lam_R, 1.2)
    lam_P, lam_R = fading_factors(np.diag([3.0, 0.5]), C, 1.5, 0.01, 100.0, multiple=True)
    assert lam_P == pytest.approx(1.5) and np.allclose(lam_R, [3.0, 0.5])


@pytest.mark.parametrize("scale,lam_p,lam_r", [(50.0, 1.5, None), (0.001, 1.0, 0.01)])
def test_ankf2_lambda_clip_in_the_filter(scale, lam_p, lam_r):
    """Huge innovations drive lambda_P to lambda_max; vanishing ones to 1 and lambda_R to the
    lower clip 0.01."""
    motion, meas, zs = _bearing_data(30)
    f = make_filter("ankf2", motion, meas, np.zeros(4), P0, window=5)
    for z in zs:
        f.predict(DT)
        pred = meas.h(f.x)
        f.update(pred + scale * meas.residual(z, pred))
    assert f.adapted
    assert f.lambda_P == pytest.approx(lam_p)
    if lam_r is not None:
        np.testing.assert_allclose(f.lambda_R, lam_r)
        np.testing.assert_allclose(f.R_used, lam_r * meas.R)


@pytest.mark.parametrize("fade_prior", [False, True])
def test_ankf2_update_is_the_joseph_update_with_faded_prior(fade_prior):
    motion, meas, zs = _bearing_data(25, sigma=0.15)
    f = make_filter("ankf2", motion, meas, np.zeros(4), P0, window=5, fade_prior=fade_prior)
    for z in zs[:-1]:
        f.step(DT, z)
    x_post, P_post = f.x.copy(), f.P.copy()
    f.predict(DT)
    F, Q = motion.transition(DT), motion.Q(DT)
    Pprop = F @ P_post @ F.T
    x_prior = F @ x_post
    np.testing.assert_allclose(f.x, x_prior, atol=1e-15)
    H = meas.H(x_prior)
    nu = meas.residual(zs[-1], meas.h(x_prior))
    f.update(zs[-1])
    C_hat = f.window.covariance()       # includes this step's innovation nu
    C = H @ (Pprop + Q) @ H.T + meas.R
    ratio = np.trace(C_hat) / np.trace(C)
    lam = min(max(ratio, 1.0), 1.5)
    Pm = lam * (Pprop + Q) if fade_prior else lam * Pprop + Q
    x_ref, P_ref, _ = kf_update(x_prior, Pm, nu, H, np.clip(ratio, 0.01, 100) * meas.R)
    assert f.lambda_P == pytest.approx(lam)
    np.testing.assert_allclose(f.x, x_ref, atol=1e-12)
    np.testing.assert_allclose(f.P, P_ref, atol=1e-12)


def test_ankf1_adapt_q_replaces_q_in_the_next_prediction():
    motion, meas, zs = _bearing_data(30, sigma=0.1)
    f = make_filter("ankf1", motion, meas, np.zeros(4), P0, window=10, adapt_q=True)
    for z in zs:
        f.step(DT, z)
    assert f.Q_hat is not None
    np.testing.assert_allclose(f.Q_hat, f.Q_hat.T)
    K = f.last.K
    C_hat = f.window.covariance()
    np.testing.assert_allclose(f.Q_hat, K @ C_hat @ K.T, atol=1e-15)
    P_post = f.P.copy()
    f.predict(DT)
    F = motion.transition(DT)
    np.testing.assert_allclose(f.P, F @ P_post @ F.T + f.Q_hat, atol=1e-14)


@pytest.mark.parametrize("kind", ["ankf1", "ankf2"])
def test_missing_cells_do_not_enter_the_window(kind):
    motion, meas, zs = _bearing_data(40, sigma=0.2)
    zs = zs.copy()
    zs[30, 1] = np.nan          # a partial measurement after adaptation started
    zs[32, :] = np.nan          # a predict-only step
    zs[3, 0] = np.nan           # a partial measurement before the window is full
    f = make_filter(kind, motion, meas, np.zeros(4), P0, window=10)
    counts = []
    for k, z in enumerate(zs):
        f.step(DT, z)
        counts.append(f.window.count)
        if k == 30:
            assert not f.adapted
            assert f.R_used.shape == (1, 1)
            if kind == "ankf1":
                np.testing.assert_allclose(f.R_used, [[f.R_hat[0]]])
            else:
                assert f.lambda_P == 1.0
                np.testing.assert_allclose(f.R_used, f.lambda_R[0] * meas.R[:1, :1])
    assert counts[-1] == 40 - 3
    assert counts[3] == counts[2] and counts[30] == counts[29] and counts[32] == counts[31]
    assert np.all(np.isfinite(f.x)) and np.all(np.linalg.eigvalsh(f.P) > 0)


def test_scale_noise_is_symmetric_for_a_full_r():
    R = np.array([[2.0, 0.5], [0.5, 1.0]])
    out = scale_noise(R, np.array([4.0, 0.25]))
    np.testing.assert_allclose(out, out.T)
    np.testing.assert_allclose(np.diag(out), [8.0, 0.25])
    np.testing.assert_allclose(scale_noise(np.diag([1.0, 3.0]), np.array([2.0, 2.0])),
                               np.diag([2.0, 6.0]))
