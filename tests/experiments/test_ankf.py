"""Seed 000 scenario 3 (`ankf`): EKF vs ANKF1/ANKF2 under a wrong noise model, paired Monte
Carlo claims (mean of per-run RMSE differences + 3 SE < 0) and the JSON contract."""

import json

import numpy as np
import pytest

from record_golden import assert_unchanged
from vtrack.cli import main
from vtrack.estimation.bounds import paired_difference
from vtrack.estimation.models import Bearings, WienerVelocity
from vtrack.experiments import _bearings_scenario as scn
from vtrack.experiments.ankf import scenarios

RUNS = 20


@pytest.fixture(scope="module")
def seeds():
    return scn.run_seeds(0, RUNS)


def _simulate(name, seeds, kinds=None):
    scenario, filters, _ = scenarios()[name]
    if kinds is not None:
        filters = {k: v for k, v in filters.items() if k in kinds}
    return scn.simulate(scenario, seeds, filters)


@pytest.fixture(scope="module")
def case_3a(seeds):
    return _simulate("3a", seeds, ("ekf", "ankf2"))


@pytest.fixture(scope="module")
def case_3b(seeds):
    return _simulate("3b-r-overestimated", seeds)


@pytest.fixture(scope="module")
def case_step(seeds):
    return _simulate("3b-r-step", seeds[:10], ("ekf", "ankf1"))


def _rmse(case, kind):
    return scn.per_run_rmse(case.runs[kind], case.truth)


@pytest.mark.parametrize("kind,opts,case", [
    ("ankf1", {}, "3b-r-overestimated"),
    ("ankf1", {"adapt_q": True, "window": 7}, "3a"),
    ("ankf2", {}, "3a"),
    ("ankf2", {"multiple_factors": True, "fade_prior": True, "lambda_max": 2.0}, "3b-r-step"),
])
def test_batched_adaptive_filters_equal_the_core_filters(seeds, kind, opts, case):
    """The experiment's batched ANKF path (core adaptive.ankf*_update with a run axis) gives
    the numbers of the per-run core filter objects (make_filter)."""
    scenario = scenarios()[case][0]
    few = seeds[:3]
    truth = scn.turning_truth(few)
    Z = scn.measure(truth, scenario.sensors, scenario.sigma_true, few)
    motion = WienerVelocity(scenario.q_filter)
    meas = Bearings(scenario.sensors, scenario.sigma_filter)
    x0s = np.zeros((3, 4))
    batched = scn.run_filter(kind, motion, meas, Z, x0s, scn.P0, **opts)
    per_run = scn.run_filter(kind, motion, meas, Z, x0s, scn.P0, batch=False, **opts)
    np.testing.assert_allclose(batched.x, per_run.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(batched.P, per_run.P, rtol=1e-9, atol=1e-12)
    assert set(batched.series) == set(per_run.series)
    for name in batched.series:
        np.testing.assert_allclose(batched.series[name], per_run.series[name], rtol=1e-9,
                                   atol=1e-15)


def test_ankf2_beats_the_ekf_in_case_3a(case_3a):
    diff = paired_difference(_rmse(case_3a, "ankf2"), _rmse(case_3a, "ekf"))
    assert diff["runs"] == RUNS  # no run diverged
    mean, se = diff["mean"], diff["se"]
    assert mean + 3 * se < 0, (mean, se)


@pytest.mark.parametrize("kind", ["ankf1", "ankf2"])
def test_adaptive_filters_beat_the_ekf_in_case_3b(case_3b, kind):
    diff = paired_difference(_rmse(case_3b, kind), _rmse(case_3b, "ekf"))
    assert diff["runs"] == RUNS  # no run diverged
    mean, se = diff["mean"], diff["se"]
    assert mean + 3 * se < 0, (mean, se)


def test_ankf1_recovers_the_true_r_in_case_3b(case_3b):
    """sigma_w assumed 0.5, true 0.05: the IAE estimate lands near 0.05^2, not 0.5^2."""
    r = case_3b.runs["ankf1"].series["R_used"][:, 250:]
    assert 0.5 * 0.05**2 < np.median(r) < 2.0 * 0.05**2


def test_ankf1_follows_the_r_step(case_step):
    """sigma_w steps 0.05 -> 0.15 at step 250: the adapted R follows (factor 2 tolerance)."""
    r = case_step.runs["ankf1"].series["R_used"]
    assert 0.5 * 0.05**2 < np.median(r[:, 50:250]) < 2.0 * 0.05**2
    assert 0.5 * 0.15**2 < np.median(r[:, 300:]) < 2.0 * 0.15**2


def test_adaptive_filters_stay_above_the_reference_floor(case_3a, case_3b):
    for case in (case_3a, case_3b):
        for kind, run in case.runs.items():
            mse_runs = np.mean(scn.squared_position_error(run, case.truth), axis=1)
            se = mse_runs.std(ddof=1) / np.sqrt(len(mse_runs))
            assert mse_runs.mean() + 3 * se >= np.mean(case.bound_var), kind


@pytest.mark.golden
def test_ankf_json(capsys):
    assert main(["experiment", "ankf", "--runs", "2", "--seed", "3", "--json"]) == 0
    out = capsys.readouterr().out
    summary = json.loads(out)
    assert_unchanged("ankf", summary)
    assert out.count("\n") == 1
    assert set(summary["results"]) == {"ekf", "ankf1", "ankf2"}
    for kind, entry in summary["results"].items():
        assert isinstance(entry["rmse"], float)
        assert isinstance(entry["anees"], float)
        assert isinstance(entry["pcrlb_rmse"], float)
        assert isinstance(entry["paper_rmse"], float)
    assert {"3b-r-overestimated", "3b-r-step"} <= set(summary["cases"])
    for body in summary["cases"].values():
        for entry in body["results"].values():
            assert isinstance(entry["rmse"], float)
    assert summary["cases"]["3b-r-step"]["parameters"]["sigma_w_true"] == {
        "before": 0.05, "after": 0.15, "change_at_step": 250}
