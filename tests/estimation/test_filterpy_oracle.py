"""EKF and UKF against filterpy (test-only oracle) on bearings-only runs, step by step.

What is compared: after every predict, the prior mean and covariance; after every update,
the posterior mean x and covariance P; absolute tolerance 1e-10 on every entry (observed
differences are ~1e-14: filterpy inverts S, the core solves with its Cholesky factor).

Oracle set-up:
- EKF: filterpy.kalman.ExtendedKalmanFilter with F, Q, R of the same models, the core's
  Bearings.h / Bearings.H, and `residual` = wrapped difference. filterpy's update is the
  Joseph form, as in the core.
- UKF: filterpy.kalman.UnscentedKalmanFilter with MerweScaledSigmaPoints(n, alpha, beta,
  kappa), which is the same scaled UT (same lambda, weights, and points m +- sqrt(c) L_i with
  L_i the columns of the lower Cholesky factor: filterpy uses rows of the upper one).
  filterpy 2.0's predict re-draws the sigma points from the predicted (x-, P-); the core's
  update does the same, so the update-step points agree. `residual_z` wraps, and `z_mean_fn`
  averages the bearings relative to the first (centre) sigma point, Y0 + sum Wm wrap(Y - Y0),
  which is exactly the core's weighted_mean with reference h(x-) = Y0.
- The CKF is not compared: filterpy's CubatureKalmanFilter updates with the propagated
  prediction points instead of points re-drawn from P- (the Q term is then missing from the
  points; the seed-000 eq. 23 typo), so it is not the standard CKF.

Runs: the seed-000 turning path with the deduced sensors (S1 bearings up to ~3 rad, so
sigma points come near the +-pi cut), and a path that passes straight behind a sensor
(bearing crosses +-pi), where the wrapping on both sides is exercised.
"""

import numpy as np
import pytest
import seed000 as S

from vtrack.filter_kinds import make_filter
from vtrack.estimation.linalg import wrap_angle

filterpy_kalman = pytest.importorskip("filterpy.kalman")

ATOL = 1e-10


def _wrapped_residual(a, b):
    return wrap_angle(np.asarray(a) - np.asarray(b))


def _circular_mean(sigmas, Wm):
    return sigmas[0] + Wm @ wrap_angle(sigmas - sigmas[0])


def _scenario(name):
    rng = np.random.default_rng(0)
    if name == "turning":
        truth = S.turning_truth(rng)
        return S.SENSORS, S.bearings(truth, rng), S.M0_FILTER, S.P0
    truth = S.crossing_truth()
    zs = S.bearings(truth, rng, S.CROSSING_SENSORS)
    assert zs[:, 0].max() > 3.0 and zs[:, 0].min() < -3.0  # it really crosses the cut
    return S.CROSSING_SENSORS, zs, S.CROSSING_X0, S.CROSSING_P0


def _compare(core, oracle_predict, oracle_update, oracle_state, zs):
    got, want = [], []
    for z in zs:
        core.predict(S.DT)
        oracle_predict()
        got.append((core.x.copy(), core.P.copy()))
        want.append(tuple(np.array(a, dtype=float) for a in oracle_state()))
        core.update(z)
        oracle_update(z)
        got.append((core.x.copy(), core.P.copy()))
        want.append(tuple(np.array(a, dtype=float) for a in oracle_state()))
    for i, what in enumerate(("x", "P")):
        a = np.array([g[i] for g in got])
        b = np.array([w[i] for w in want])
        bad = np.abs(a - b).reshape(len(a), -1).max(axis=1) > ATOL
        if bad.any():
            k = int(np.argmax(bad))
            stage = "prior (after predict)" if k % 2 == 0 else "posterior (after update)"
            np.testing.assert_allclose(a[k], b[k], rtol=0, atol=ATOL,
                                       err_msg=f"{stage} {what} differs at step {k // 2}")


@pytest.mark.parametrize("scenario", ["turning", "crossing"])
def test_ekf_matches_filterpy(scenario):
    sensors, zs, x0, P0 = _scenario(scenario)
    motion, meas = S.models(sensors)
    core = make_filter("ekf", motion, meas, x0, P0)
    ekf = filterpy_kalman.ExtendedKalmanFilter(dim_x=4, dim_z=2)
    ekf.x, ekf.P = x0.copy(), P0.copy()
    ekf.F, ekf.Q, ekf.R = motion.transition(S.DT), motion.Q(S.DT), meas.R.copy()
    _compare(core, ekf.predict,
             lambda z: ekf.update(z, meas.H, meas.h, residual=_wrapped_residual),
             lambda: (ekf.x, ekf.P), zs)


@pytest.mark.parametrize("scenario", ["turning", "crossing"])
@pytest.mark.parametrize("alpha,beta,kappa", [(1.0, 0.0, -1.0), (0.5, 2.0, 0.0)])
def test_ukf_matches_filterpy(scenario, alpha, beta, kappa):
    sensors, zs, x0, P0 = _scenario(scenario)
    motion, meas = S.models(sensors)
    F = motion.transition(S.DT)
    core = make_filter("ukf", motion, meas, x0, P0, alpha=alpha, beta=beta, kappa=kappa)
    points = filterpy_kalman.MerweScaledSigmaPoints(4, alpha=alpha, beta=beta, kappa=kappa)
    np.testing.assert_allclose(points.Wm, core.rule.Wm, rtol=1e-15)
    np.testing.assert_allclose(points.Wc, core.rule.Wc, rtol=1e-15)
    ukf = filterpy_kalman.UnscentedKalmanFilter(
        dim_x=4, dim_z=2, dt=S.DT, hx=meas.h, fx=lambda x, dt: F @ x, points=points,
        z_mean_fn=_circular_mean, residual_z=_wrapped_residual)
    ukf.x, ukf.P = x0.copy(), P0.copy()
    ukf.Q, ukf.R = motion.Q(S.DT), meas.R.copy()
    _compare(core, ukf.predict, ukf.update, lambda: (ukf.x, ukf.P), zs)


def test_toolbox_weights_are_seed000_eq10():
    """alpha=1, beta=0, kappa=3-n: lambda=-1, W0 = -1/3, Wi = 1/6 for n = 4 (SEEDS 1.3)."""
    motion, meas = S.models()
    rule = make_filter("ukf", motion, meas, S.M0_FILTER, S.P0).rule
    np.testing.assert_allclose(rule.Wm, [-1 / 3] + [1 / 6] * 8, rtol=1e-15)
    np.testing.assert_allclose(rule.Wc, rule.Wm, rtol=1e-15)
    assert rule.spread == pytest.approx(np.sqrt(3.0))
