"""Seed 002 robot experiment: UKF, SR-UKF and the paper's cube-root variant (crukf)."""

import json
from dataclasses import replace

import numpy as np
import pytest

from vtrack.experiments import robot as rb
from vtrack.experiments._mcutil import run_generators


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


def test_json_schema_and_determinism(small_robot, cli_stdout):
    out1 = cli_stdout(["experiment", "robot", "--runs", "2", "--seed", "3", "--json"])
    out2 = cli_stdout(["experiment", "robot", "--runs", "2", "--seed", "3", "--json"])
    assert out1 == out2
    data = json.loads(out1)
    assert set(data["results"]) == {"ukf", "srukf", "crukf"}
    assert "unsound" in data["description"] and "EXPERIMENTAL" in data["description"]
    for kind in ("ukf", "srukf"):
        entry = data["results"][kind]
        for key in ("rmse", "eps_x", "eps_theta", "pi", "anees"):
            assert isinstance(entry[key], float)
        assert isinstance(entry["downdate_fallbacks"], int)
    assert data["results"]["ukf"]["paper"]["eps_x"] == [0.0082, 0.0050, 0.0074]
    case = data["cases"]["unicycle-alpha1"]["results"]
    assert case["srukf"]["rmse"] == pytest.approx(case["ukf"]["rmse"], rel=1e-9)
