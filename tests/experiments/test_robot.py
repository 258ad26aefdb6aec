"""Seed 002 robot experiment: UKF, SR-UKF and the paper's cube-root variant (crukf), beside
the EKF and the iterated kinds, and the robot's PCRLB."""

import json
from dataclasses import replace

import numpy as np
import pytest

from record_golden import assert_unchanged
from vtrack.estimation.montecarlo import run_generators
from vtrack.experiments import robot as rb


def _data(cfg, seed=0):
    (truth_rng, filt_rng), = run_generators(seed, 1)
    truth, z = rb.simulate(cfg, truth_rng)
    xhat0 = filt_rng.multivariate_normal(np.array(cfg.x0), np.diag(cfg.P0))
    return truth, z, xhat0


@pytest.mark.parametrize("noise", ["augmented", "additive"])
def test_ukf_equals_srukf_when_alpha_is_one(noise):
    """SEEDS 1.5 check on the robot itself: alpha = 1 (Wc0 > 0) -> same estimates to ~1e-9."""
    cfg = replace(rb.UNICYCLE, alpha=1.0, beta=2.0, kappa=0.0, noise=noise, steps=150)
    _, z, xhat0 = _data(cfg)
    x_u, P_u, _ = rb.run_filter("ukf", cfg, xhat0, z)
    x_s, P_s, counts = rb.run_filter("srukf", cfg, xhat0, z)
    assert counts["fallbacks"] == 0 and counts["repairs"] == 0
    np.testing.assert_allclose(x_s, x_u, rtol=0, atol=1e-9)
    np.testing.assert_allclose(P_s, P_u, rtol=0, atol=1e-9)


@pytest.mark.parametrize("kind", ["ukf", "srukf"])
@pytest.mark.parametrize("alpha,tol", [(1.0, 1e-9), (1e-4, 1e-6)])
def test_augmented_filter_equals_the_kf_on_a_linear_robot(kind, alpha, tol):
    """With c1 = c2 = 0 the robot is linear with additive noise: the augmented-state sigma-
    point filters must give the KF's (EKF's) mean and covariance, for any alpha."""
    cfg = replace(rb.UNICYCLE, c1=0.0, c2=0.0, alpha=alpha, beta=2.0, kappa=0.0, steps=100)
    _, z, xhat0 = _data(cfg, seed=3)
    x_f, P_f, _ = rb.run_filter(kind, cfg, xhat0, z)
    kf = rb.make_filter("ekf", rb.AdditiveRobotMotion(cfg), rb.pose_measurement(np.sqrt(cfg.V)),
                        xhat0, np.diag(cfg.P0))
    for k, zk in enumerate(z, start=1):
        kf.step(1.0, zk)
        assert np.abs(kf.x - x_f[k]).max() < tol
        assert np.abs(kf.P - P_f[k]).max() < tol


def test_ukf_not_worse_than_the_cube_root_variant():
    """Paired per-run eps_x and eps_theta (crukf - ukf): the cube-root variant is never
    better by more than 3 standard errors, and its NEES is further from 3 (unsound P)."""
    cfg = replace(rb.UNICYCLE, alpha=1.0, beta=2.0, kappa=0.0, steps=200)
    res, _ = rb.run_case(cfg, 5, seed=2)
    for metric in ("eps_x_minus_ukf", "eps_theta_minus_ukf"):
        d = res["crukf"][metric]
        assert d["mean"] + 3 * d["se"] >= 0, (metric, d)
    assert abs(res["ukf"]["anees"] - 3.0) < 1.0
    assert abs(res["crukf"]["anees"] - 3.0) > abs(res["ukf"]["anees"] - 3.0)


def test_paper_alpha_makes_the_cube_root_variant_diverge():
    """At alpha = 1e-4 its gain is inflated ~(L+lambda)^(-1/3) ~ 230: it needs repairs from
    step 1 and diverges, while the UKF and SR-UKF agree and do not."""
    cfg = replace(rb.PAPER, steps=60)
    res, _ = rb.run_case(cfg, 2, seed=0)
    assert res["crukf"]["runs_needing_repair"] == 2
    assert res["crukf"]["first_repair_step_median"] == 1.0
    assert res["crukf"]["diverged_runs"] == 2
    assert res["ukf"]["diverged_runs"] == 0 and res["srukf"]["diverged_runs"] == 0
    assert res["srukf"]["eps_x"] == pytest.approx(res["ukf"]["eps_x"], rel=1e-6)


def test_augmented_ukf_is_consistent_on_the_unicycle():
    cfg = replace(rb.UNICYCLE, steps=200)
    res, _ = rb.run_case(cfg, 4, seed=5, kinds=("ukf",))
    assert 2.0 < res["ukf"]["anees"] < 4.2
    assert res["ukf"]["rmse"] < 0.01


@pytest.fixture
def small_robot(monkeypatch):
    monkeypatch.setattr(rb, "PAPER", replace(rb.PAPER, steps=40))
    monkeypatch.setattr(rb, "CASES", {
        "unicycle-alpha1": (replace(rb.UNICYCLE, alpha=1.0, beta=2.0, kappa=0.0, steps=40),
                            "small", True)})


@pytest.mark.golden
def test_json_schema_and_determinism(small_robot, cli_stdout):
    out1 = cli_stdout(["experiment", "robot", "--runs", "2", "--seed", "3", "--json"])
    out2 = cli_stdout(["experiment", "robot", "--runs", "2", "--seed", "3", "--json"])
    assert out1 == out2
    data = json.loads(out1)
    assert_unchanged("robot", data)
    assert set(data["results"]) == {"ukf", "srukf", "crukf", "ekf", "iekf", "iplf"}
    assert "unsound" in data["description"] and "EXPERIMENTAL" in data["description"]
    for kind in ("ukf", "srukf"):
        entry = data["results"][kind]
        for key in ("rmse", "eps_x", "eps_theta", "pi", "anees"):
            assert isinstance(entry[key], float)
        assert isinstance(entry["downdate_fallbacks"], int)
    assert data["results"]["ukf"]["paper"]["eps_x"] == [0.0082, 0.0050, 0.0074]
    case = data["cases"]["unicycle-alpha1"]["results"]
    assert case["srukf"]["rmse"] == pytest.approx(case["ukf"]["rmse"], rel=1e-9)


def test_pcrlb_of_a_robot_that_does_not_move_is_the_kf_covariance():
    """Independent reference: with c1 = c2 = 0 the truth x' = x + w is linear-Gaussian with
    the pose measured, so the PCRLB is the KF's covariance from P0 (Riccati recursion)."""
    cfg = replace(rb.UNICYCLE, c1=0.0, c2=0.0, steps=30)
    truth = np.array([rb.simulate(cfg, rng)[0] for rng, _ in run_generators(0, 3)])
    P = np.diag(cfg.P0)
    W, V = np.diag(cfg.W), np.diag(cfg.V)
    expected = []
    for _ in range(cfg.steps):
        P = P + W
        P = P - P @ np.linalg.solve(P + V, P)
        expected.append(P[0, 0] + P[1, 1])
    np.testing.assert_allclose(rb.pcrlb_position(truth, cfg), expected, rtol=1e-9)


def test_filters_are_at_the_pcrlb_on_the_unicycle_and_iterating_changes_nothing():
    """The well-posed unicycle (x0-hat ~ N(x0, P0): the bound is strict): the EKF and UKF
    position RMSE are within 10 % of the PCRLB and not below it beyond Monte Carlo error
    (measured 10 runs: 1.002); the pose measurement is linear, so iekf equals the EKF."""
    cfg = replace(rb.UNICYCLE, steps=150)
    res, _ = rb.run_case(cfg, 6, seed=4, kinds=("ukf", "ekf", "iekf"))
    for kind in ("ukf", "ekf"):
        assert 0.9 < res[kind]["rmse_over_pcrlb"] < 1.1, (kind, res[kind])
    assert res["iekf"]["rmse"] == pytest.approx(res["ekf"]["rmse"], rel=1e-9)
    assert res["iekf"]["anees"] == pytest.approx(res["ekf"]["anees"], rel=1e-9)


def test_stacked_cube_root_runs_repair_each_run_as_alone():
    """The cube-root variant falls back to the full covariance and repairs it in most steps;
    a stack of runs does that for the failing runs together (one factorisation of their
    stack), and must give each run what it gets alone: estimates within 1e-9 relative, the same
    fallback and repair counts."""
    cfg = replace(rb.PAPER, steps=8)          # before its divergence amplifies rounding
    runs = run_generators(7, 4)
    data = [rb.simulate(cfg, t) for t, _ in runs]
    x0 = np.array([f.multivariate_normal(np.array(cfg.x0), np.diag(cfg.P0)) for _, f in runs])
    Z = np.stack([z for _, z in data])
    flt = rb.build_filter("crukf", cfg, x0)
    stacked = rb.run_sequence(flt, Z, 1.0, record=rb.COUNTERS)
    assert stacked.series["repairs"][-1].min() > 0
    for r in range(len(runs)):
        alone = rb.run_sequence(rb.build_filter("crukf", cfg, x0[r]), Z[r], 1.0,
                                record=rb.COUNTERS)
        np.testing.assert_allclose(stacked.x[r], alone.x, rtol=1e-9, atol=1e-9)
        for key in ("fallbacks", "repairs"):
            assert np.array_equal(stacked.series[key][r], alone.series[key])
