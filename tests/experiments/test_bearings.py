"""Seed 000 scenarios 1 and 2 (`bearings-2`, `bearings-3`): paired Monte Carlo claims and the
`vtrack experiment` JSON contract.

Every comparison is PAIRED (same runs: same truth, same noise of the shared sensors) and uses
the margin "mean of the per-run differences +- 3 standard errors". 16 runs keep the file fast.
"""

import json

import numpy as np
import pytest
from scipy.linalg import expm

from record_golden import assert_unchanged
from vtrack.cli import main
from vtrack.estimation.bounds import chi2_band, paired_difference
from vtrack.estimation.models import Bearings, WienerVelocity
from vtrack.experiments import _bearings_scenario as scn
from vtrack.experiments.bearings import KINDS

RUNS = 16
# The seed paper's filters; the iterated kinds are tested on their own case in
# tests/estimation/test_iterated.py (and their JSON entries below).
FILTERS = {"ekf": {}, "ukf": {}, "ckf": {}}


@pytest.fixture(scope="module")
def seeds():
    return scn.run_seeds(0, RUNS)


@pytest.fixture(scope="module")
def two(seeds):
    return scn.simulate(scn.Scenario(scn.SENSORS_DEDUCED), seeds, FILTERS)


@pytest.fixture(scope="module")
def three(seeds):
    return scn.simulate(scn.Scenario(scn.SENSORS_THREE), seeds, FILTERS)


@pytest.fixture(scope="module")
def matched(seeds):
    return scn.simulate(scn.Scenario(scn.SENSORS_DEDUCED, truth="wiener"), seeds,
                        {"ekf": {}, "ukf": {}})


def _rmse(case, kind):
    return scn.per_run_rmse(case.runs[kind], case.truth)


# ------------------------------------------------------------------------- the set-up


def test_turn_transition_is_expm():
    for a in (0.0, 1e-14, 0.7, scn.TURN_RATE, -3.0):
        Fc = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, a], [0, 0, -a, 0]], float)
        np.testing.assert_allclose(scn.turn_transition(a, scn.DT), expm(Fc * scn.DT),
                                   rtol=0, atol=1e-15)


def test_turning_truth_is_the_toolbox_u_path(two):
    tr = two.truth
    assert tr.shape == (RUNS, 500, 4)
    np.testing.assert_allclose(np.hypot(tr[..., 2], tr[..., 3]), 1.0, atol=1e-12)  # speed 1
    # a clockwise "U" spanning x in [-0.83, 0.81], y in [-1.64, 0] (SEEDS 2.3)
    assert -0.9 < tr[..., 0].min() < -0.75 and 0.75 < tr[..., 0].max() < 0.9
    assert -1.7 < tr[..., 1].min() < -1.55 and tr[..., 1].max() < 0.01
    np.testing.assert_allclose(tr[:, -1, 2:], [[0.0, 1.0]] * RUNS, atol=0.05)  # heading up


def test_three_sensors_form_the_equilateral_triangle():
    s = scn.SENSORS_THREE
    sides = [np.linalg.norm(s[i] - s[(i + 1) % 3]) for i in range(3)]
    np.testing.assert_allclose(sides, 4.0, rtol=1e-12)


def test_adding_a_sensor_keeps_the_other_sensors_noise(two, three):
    np.testing.assert_array_equal(two.Z, three.Z[:, :, :2])


def test_batched_ekf_equals_the_core_ekf(two):
    motion = WienerVelocity(scn.Q_TRUE)
    meas = Bearings(scn.SENSORS_DEDUCED, scn.SIGMA_W)
    per_run = scn.run_filter("ekf", motion, meas, two.Z[:4], two.x0s[:4], scn.P0, batch=False)
    batched = two.runs["ekf"]
    np.testing.assert_allclose(batched.x[:4], per_run.x, rtol=0, atol=1e-10)
    np.testing.assert_allclose(batched.P[:4], per_run.P, rtol=0, atol=1e-10)


# ---------------------------------------------------------------------- paired claims


@pytest.mark.parametrize("kind", FILTERS)
def test_third_sensor_lowers_rmse(two, three, kind):
    diff = paired_difference(_rmse(three, kind), _rmse(two, kind))
    assert diff["runs"] == RUNS  # no run diverged
    mean, se = diff["mean"], diff["se"]
    assert mean + 3 * se < 0, (mean, se)
    # and by a lot (SEEDS 2.5: ~45 %)
    assert np.mean(_rmse(three, kind)) < 0.75 * np.mean(_rmse(two, kind))


@pytest.mark.parametrize("geometry", ["two", "three"])
@pytest.mark.parametrize("kind", ["ukf", "ckf"])
def test_sigma_point_filters_match_the_ekf(request, geometry, kind):
    """The paper's "UKF clearly best" is tested, not assumed. Measured (100 runs): the three
    filters agree to ~0.1 %; with three sensors the UKF and CKF are even 0.13 % WORSE than the
    EKF, a difference the paired runs resolve (SE 0.01 %). So the claim tested is practical
    equivalence: not worse than the EKF beyond 3 SE plus 0.5 % of the EKF's RMSE, and not
    better by more than 1 % (SEEDS 2.5: EKF ~ UKF ~ CKF within ~1 %)."""
    case = request.getfixturevalue(geometry)
    ekf = _rmse(case, "ekf")
    diff = paired_difference(_rmse(case, kind), ekf)
    assert diff["runs"] == RUNS  # no run diverged
    mean, se = diff["mean"], diff["se"]
    assert mean - 3 * se <= 0.005 * ekf.mean(), (mean, se)
    assert mean + 3 * se >= -0.01 * ekf.mean(), (mean, se)


@pytest.mark.parametrize("case_name", ["two", "three", "matched"])
def test_rmse_stays_near_or_above_the_pcrlb(request, case_name):
    """Mean squared position error over runs and steps (+ 3 SE over runs) >= the bound's mean.
    Strict in the model-matched case, a reference floor for the turning truth."""
    case = request.getfixturevalue(case_name)
    for kind, run in case.runs.items():
        mse_runs = np.mean(scn.squared_position_error(run, case.truth), axis=1)
        se = mse_runs.std(ddof=1) / np.sqrt(len(mse_runs))
        assert mse_runs.mean() + 3 * se >= np.mean(case.bound_var), kind


def test_pcrlb_reference_values(two, three):
    """The bound of SEEDS 7.2 [V]: 0.079 (deduced pair) and 0.048 (three sensors)."""
    assert np.sqrt(np.mean(two.bound_var)) == pytest.approx(0.079, abs=0.004)
    assert np.sqrt(np.mean(three.bound_var)) == pytest.approx(0.048, abs=0.003)


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_model_matched_anees_in_chi2_band(matched, kind):
    """Model-matched truth: the run- and time-averaged NEES lies in the 95 % band of the
    per-step average over the runs (the time average only narrows the spread)."""
    ne = scn.nees_series(matched.runs[kind], matched.truth)
    lo, hi = chi2_band(4, RUNS)
    assert lo <= ne.mean() <= hi, ne.mean()


def test_turning_truth_makes_the_filters_overconfident(two):
    """Model mismatch (turns the Wiener-velocity model does not expect): ANEES well above 4."""
    assert scn.nees_series(two.runs["ekf"], two.truth).mean() > chi2_band(4, RUNS)[1]


# ------------------------------------------------------------------------------- CLI


def _cli(capsys, *args):
    assert main(list(args)) == 0
    return capsys.readouterr().out


def test_experiment_list(capsys):
    names = _cli(capsys, "experiment", "--list").split()
    assert {"bearings-2", "bearings-3", "ankf"} <= set(names)


def _check_results(results, kinds):
    assert set(results) == set(kinds)
    for kind, entry in results.items():
        for key in ("rmse", "rmse_mean_of_runs", "median", "pcrlb_rmse", "anees"):
            assert isinstance(entry[key], float), (kind, key)
        assert isinstance(entry["diverged"], int)


@pytest.mark.golden
@pytest.mark.parametrize("name,cases", [
    ("bearings-2", {"toolbox-sensors", "model-matched", "precise-sensors"}),
    ("bearings-3", {"model-matched"}),
])
def test_json_schema_and_same_seed_same_json(capsys, tmp_path, name, cases):
    out = _cli(capsys, "experiment", name, "--runs", "2", "--seed", "7", "--json",
               "--plot", str(tmp_path / "plot.png"))
    summary = json.loads(out)          # exactly one JSON object and nothing else
    assert_unchanged(name, summary)    # outputs of the kinds before the refactor
    assert out.strip().startswith("{") and out.count("\n") == 1
    _check_results(summary["results"], KINDS)
    for kind in ("ekf", "ukf", "ckf"):
        assert isinstance(summary["results"][kind]["paper_rmse"], float)
    assert set(summary["cases"]) == cases
    for body in summary["cases"].values():
        _check_results(body["results"], KINDS)
    assert summary["runs"] == 2 and summary["seed"] == 7 and len(summary["run_seeds"]) == 2
    assert (tmp_path / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["plot.png"]     # no temporary left
    if name == "bearings-2":
        again = _cli(capsys, "experiment", name, "--runs", "2", "--seed", "7", "--json")
        assert again == out
