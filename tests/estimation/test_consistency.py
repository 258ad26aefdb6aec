"""Monte Carlo consistency (ANEES) and paired RMSE comparisons on the seed-000 geometry.

Set-up: deduced two-sensor geometry S1 = (1, -2), S2 = (1, 2), sigma = 0.05 rad, the filter's
Wiener-velocity model with q = 0.1, dt = 0.01, 500 steps per run.

Monte Carlo is run with seed000.run_batch (the same filter over all runs at once, built on the
core's kf_predict/kf_update, SigmaPointRule, Bearings.h/H and wrapped residuals);
`test_batch_runner_reproduces_core_filters` pins it to the core filter objects to 1e-9, so
what is shown for the batch runner holds for `make_filter("ukf"/"ckf"/"ekf")`.
"""

import numpy as np
import pytest
import seed000 as S

from vtrack.estimation.bounds import chi2_band, nees

RUNS = 100
STEPS = 500
NEAR_SENSOR = 0.2


@pytest.fixture(scope="module")
def matched():
    """Model-matched truth: x0 ~ N(m0, P0), m0 = [0, 0, 1, 0], P0 = diag(0.1, 0.1, 10, 10),
    trajectories drawn from the filter's own model, the filter's prior is (m0, P0).

    Trajectories whose true path comes within NEAR_SENSOR = 0.2 of a sensor are redrawn
    (about 7% of draws: with a velocity prior of std 3.2 the target sometimes runs through
    a sensor). There the bearing swings by ~pi within a few steps, the posterior is far from
    Gaussian and no Gaussian filter is consistent: in 40 seeds of 100 unconditioned runs,
    one such run (per-run ANEES 130-250) pushed the average out of the band in 1 seed for
    the UKF and 2 for the CKF. That regime is not what this test is about (the +-pi bearing
    crossing is covered by test_bearing_wrap). The conditioning changes the truth
    distribution slightly; with it, the time-averaged ANEES over 40 seeds was 4.00 +- 0.12
    (UKF) and 4.00 +- 0.12 (CKF).
    """
    rng = np.random.default_rng(2024)
    truth = S.model_matched_truth(rng, 2 * RUNS, STEPS)
    dist = np.linalg.norm(truth[:, :, None, :2] - S.SENSORS, axis=-1).min(axis=(1, 2))
    keep = np.flatnonzero(dist > NEAR_SENSOR)
    rejected = int(np.sum(dist[: keep[RUNS - 1] + 1] <= NEAR_SENSOR))
    truth = truth[keep[:RUNS]]
    zs = S.bearings(truth, rng)
    est = {kind: S.run_batch(kind, zs, x0=S.M0_TRUE) for kind in ("ekf", "ukf", "ckf")}
    return truth, zs, est, rejected


def _anees(truth, xs, Ps):
    """NEES per run and step (RUNS, STEPS), and its average over runs then time."""
    eps = nees(truth - xs, Ps)
    return eps, float(eps.mean())


def _rmse_per_run(truth, xs):
    return np.sqrt(np.mean(np.sum((truth - xs)[..., :2] ** 2, axis=-1), axis=1))


def test_batch_runner_reproduces_core_filters(matched):
    truth, zs, est, _ = matched
    for kind in ("ekf", "ukf", "ckf"):
        for r in (0, 1):
            xs, Ps, _ = S.run(kind, zs[r], x0=S.M0_TRUE)
            np.testing.assert_allclose(est[kind][0][r], xs, rtol=0, atol=1e-9)
            np.testing.assert_allclose(est[kind][1][r], Ps, rtol=0, atol=1e-9)


@pytest.mark.parametrize("kind", ["ukf", "ckf"])
def test_time_averaged_anees_in_chi2_band(matched, kind):
    """Time-averaged ANEES (mean over the M = 100 runs, then over the K = 500 steps) lies in
    chi2_band(4, M), the two-sided 95% band of an average of M independent chi2(4) values.

    Why this band: the runs are independent, the steps within a run are not (consecutive
    errors at dt = 0.01 are nearly identical). Each run's time average a_i has mean 4 for a
    consistent filter and variance between 8/K (independent steps) and 8 (fully correlated
    steps); the average of M of them therefore has variance <= 8/M, which is exactly the
    variance behind the per-step band for M runs. Applied to the time average that band is
    conservative (false-alarm rate <= ~5%). The band for M*K samples (4 +- 0.035 here) would
    assume independence over time, which is false: the measured standard deviation of the
    a_i is ~1.0 (it would be sqrt(8/500) = 0.13 for independent steps), i.e. only ~8
    effectively independent samples per run, not 500, and that band would reject a
    consistent filter (here it is [3.975, 4.025]). As a sharper second check that uses the independence of
    the runs only, the ANEES must also lie within 3 empirical standard errors of 4.
    """
    truth, _, est, rejected = matched
    assert rejected < 0.2 * RUNS
    eps, anees = _anees(truth, *est[kind])
    lo, hi = chi2_band(4, RUNS)
    assert lo <= anees <= hi, f"{kind} ANEES {anees:.3f} outside [{lo:.3f}, {hi:.3f}]"
    per_run = eps.mean(axis=1)
    se = per_run.std(ddof=1) / np.sqrt(RUNS)
    assert abs(anees - 4.0) <= 3 * se, f"{kind} ANEES {anees:.3f}, SE {se:.3f}"


def test_control_overconfident_filter_fails_the_band(matched):
    """Power check: a UKF told sigma = 0.025 (R four times too small) on the same data is
    overconfident and must land above the band (observed ~10)."""
    truth, zs, _, _ = matched
    _, anees = _anees(truth, *S.run_batch("ukf", zs, x0=S.M0_TRUE, sigma=0.025))
    assert anees > chi2_band(4, RUNS)[1]


def _paired(rm_a, rm_b):
    d = rm_a - rm_b
    return d.mean(), d.std(ddof=1) / np.sqrt(len(d))


@pytest.mark.parametrize("a,b", [("ekf", "ukf"), ("ckf", "ukf")])
def test_paired_rmse_equivalent_model_matched(matched, a, b):
    """Paired per-run RMSE difference (same truth and measurements for both filters):
    |mean| + 3 SE <= 2% of the mean RMSE, i.e. "equal within 2%" is shown, not assumed
    (observed: differences ~0.1% with SE ~0.2%)."""
    truth, _, est, _ = matched
    rm_a, rm_b = _rmse_per_run(truth, est[a][0]), _rmse_per_run(truth, est[b][0])
    mean, se = _paired(rm_a, rm_b)
    assert abs(mean) + 3 * se <= 0.02 * rm_b.mean(), (mean, se, rm_b.mean())


@pytest.fixture(scope="module")
def turning():
    """The paper's scenario: the toolbox's turning path (not a sample of the filter's
    model), prior m0 = [0, 0, 0, 0], P0 = diag(0.1, 0.1, 10, 10), 50 runs."""
    rng = np.random.default_rng(7)
    truth = np.array([S.turning_truth(rng) for _ in range(50)])
    zs = S.bearings(truth, rng)
    return truth, {kind: S.run_batch(kind, zs)[0] for kind in ("ekf", "ukf", "ckf")}


@pytest.mark.parametrize("a,b", [("ekf", "ukf"), ("ckf", "ukf"), ("ekf", "ckf")])
def test_paired_rmse_turning_path(turning, a, b):
    """SEEDS 2.5: EKF ~ UKF ~ CKF within ~1% on the seed-000 turning path (the paper's "UKF
    clearly best" is not expected to reproduce): |mean paired difference| + 3 SE <= 1% of
    the mean RMSE. Also the RMSE level: about 0.115 [V], accepted in [0.09, 0.14]."""
    truth, xs = turning
    rm_a, rm_b = _rmse_per_run(truth, xs[a]), _rmse_per_run(truth, xs[b])
    mean, se = _paired(rm_a, rm_b)
    assert abs(mean) + 3 * se <= 0.01 * rm_b.mean(), (mean, se, rm_b.mean())
    assert 0.09 < rm_b.mean() < 0.14


@pytest.mark.parametrize("n", [1, 3, 4, 9, 18])
def test_nees_of_a_stack_factors_elementwise_as_lapack_solves(n):
    """nees on a stack of >= ELEMENTWISE_FROM matrices (Cholesky, elementwise over the stack)
    equals e' P^-1 e by LAPACK's solve within 1e-12 relative (well-conditioned P: cond <=
    ~1e3 here), and a matrix that is not positive definite gets LAPACK's number, not NaN."""
    from vtrack.estimation.bounds import ELEMENTWISE_FROM

    rng = np.random.default_rng(n)
    A = rng.normal(size=(3, ELEMENTWISE_FROM, n, n))
    P = A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(n)
    P[1, 7] = -P[1, 7]                                   # negative definite
    e = rng.normal(size=(3, ELEMENTWISE_FROM, n))
    want = np.einsum("...i,...i->...", e, np.linalg.solve(P, e[..., None])[..., 0])
    got = nees(e, P)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
    assert got[1, 7] < 0
    # a small stack and a single matrix take LAPACK's path, to the same numbers
    np.testing.assert_allclose(nees(e[0, :5], P[0, :5]), want[0, :5], rtol=1e-12, atol=0)
    np.testing.assert_allclose(nees(e[2, 3], P[2, 3]), want[2, 3], rtol=1e-12, atol=0)
