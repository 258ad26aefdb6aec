"""The smoother of a gap of predictions (kalman.smooth_gap) against filterpy's batch
Rauch-Tung-Striebel smoother (test-only oracle), and its consistency on simulated gaps."""

import numpy as np
import pytest
from scipy.stats import chi2

from vtrack.estimation.kalman import kf_predict, kf_update, smooth_gap
from vtrack.estimation.linalg import NotPositiveDefiniteError
from vtrack.estimation.models import ConstantAcceleration

filterpy_kalman = pytest.importorskip("filterpy.kalman")

DT, Q_JERK, SIGMA = 0.04, 1e4, 2.0
H = np.eye(2, 6)
R = SIGMA**2 * np.eye(2)


def _gap_run(rng, before=10, gap=12):
    """A constant-acceleration target detected `before` frames, lost for `gap`, detected
    once more. Returns truth (T, 6), filtered / predicted (x, P) per frame, the prior of the
    last update, and the detected mask."""
    model = ConstantAcceleration(Q_JERK)
    F, Q = model.transition(DT), model.Q(DT)
    n = before + gap + 1
    truth = np.zeros((n, 6))
    truth[0] = [100, 50, 80, -30, 5, 10]
    for k in range(1, n):
        truth[k] = F @ truth[k - 1] + rng.multivariate_normal(np.zeros(6), Q)
    detected = np.ones(n, dtype=bool)
    detected[before:before + gap] = False
    x, P = truth[0] + rng.normal(0, [2, 2, 20, 20, 50, 50]), np.diag([4, 4, 400, 400, 2500, 2500.0])
    xs, Ps, prior = [], [], None
    for k in range(n):
        if k:
            x, P = kf_predict(x, P, F, Q)
        if detected[k]:
            prior = (x.copy(), P.copy())
            z = truth[k, :2] + rng.normal(0, SIGMA, 2)
            x, P, _ = kf_update(x, P, z - H @ x, H, R)
        xs.append(x.copy())
        Ps.append(P.copy())
    return truth, np.array(xs), np.array(Ps), prior, detected, F, Q, model


def _smoothed_gap(xs, Ps, prior, detected, model):
    """smooth_gap over the lost frames of a `_gap_run`, ended by its last frame's update;
    returns the gap's frame indices, their transitions to the last frame and the means."""
    gap = np.flatnonzero(~detected)
    t_end = len(xs) - 1
    Phi = np.array([model.transition(DT * (t_end - j)) for j in gap])
    return gap, Phi, smooth_gap(xs[gap], Ps[gap], Phi, prior[0], prior[1], xs[t_end])


def test_matches_filterpy_rts_smoother_on_the_gap():
    rng = np.random.default_rng(3)
    truth, xs, Ps, prior, detected, F, Q, model = _gap_run(rng)
    n = len(xs)
    # filterpy's batch smoother over the whole run; with no update after the last frame,
    # its smoothed last state is the filtered one, so the gap's smoothed states are exact.
    kf = filterpy_kalman.KalmanFilter(dim_x=6, dim_z=2)
    want, _, _, _ = kf.rts_smoother(xs, Ps, Fs=[F] * n, Qs=[Q] * n)
    gap, _, got = _smoothed_gap(xs, Ps, prior, detected, model)
    np.testing.assert_allclose(got, want[gap], rtol=0, atol=1e-8)
    assert np.abs(got - xs[gap]).max() > 0.1   # the gap's states really moved


def test_smoothed_gap_is_consistent_and_closer_to_the_truth():
    """Over 300 simulated gaps the smoothed positions' errors are within the chi-square band
    of their smoothed covariances, and smaller than the predictions'."""
    rng = np.random.default_rng(7)
    nees, err_pred, err_smooth = [], [], []
    for _ in range(300):
        truth, xs, Ps, prior, detected, F, Q, model = _gap_run(rng)
        gap, Phi, got = _smoothed_gap(xs, Ps, prior, detected, model)
        t_end = len(xs) - 1
        # smoothed covariance: P_j - C (P_prior - P_post) C', C = P_j Phi' P_prior^-1
        C = Ps[gap] @ np.swapaxes(Phi, 1, 2) @ np.linalg.inv(prior[1])
        Pst = Ps[gap] - C @ (prior[1] - Ps[t_end]) @ np.swapaxes(C, 1, 2)
        e = (truth[gap] - got)[:, :2]
        nees.extend(np.einsum("ki,kij,kj->k", e, np.linalg.inv(Pst[:, :2, :2]), e))
        err_pred.extend(np.hypot(*(truth[gap] - xs[gap])[:, :2].T))
        err_smooth.extend(np.hypot(*e.T))
    # the mean of N chi-square(2) draws, correlated along each gap: a wide two-sided band
    mean = np.mean(nees)
    assert chi2.ppf(0.005, 2 * 300) / 300 < mean < chi2.ppf(0.995, 2 * 300) / 300 * 1.5, mean
    print(f"smoothed-gap ANEES {mean:.2f} (2 consistent); mean position error {np.mean(err_smooth):.2f} px smoothed, {np.mean(err_pred):.2f} px predicted")
    assert np.mean(err_smooth) < 0.6 * np.mean(err_pred)


def test_a_prior_that_is_not_positive_definite_is_a_clear_error():
    x = np.zeros((1, 6))
    P = np.eye(6)[None]
    with pytest.raises(NotPositiveDefiniteError, match="prior covariance"):
        smooth_gap(x, P, np.eye(6)[None], np.zeros(6), -np.eye(6), np.ones(6))
