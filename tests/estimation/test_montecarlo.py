"""The Monte Carlo harness (vtrack.estimation.montecarlo): one filter over a sequence, over a
Monte Carlo set with failing runs, the NIS test of one run, and the runs stepped together as
one stack of the core filter (equal to each run alone)."""

import numpy as np
import pytest

from vtrack.estimation.bounds import chi2_band
from vtrack.estimation.linalg import NotPositiveDefiniteError
from vtrack.estimation.models import Bearings, WienerVelocity, position_measurement
from vtrack.estimation.montecarlo import (
    StepError,
    missing_patterns,
    monte_carlo,
    nis_consistency,
    run_rmse,
    run_sequence,
    squared_error,
)
from vtrack.filter_kinds import make_filter

SENSORS = np.array([[1.0, -2.0], [1.0, 2.0]])
X0, P0 = np.array([0.0, 0.0, 1.0, 0.0]), np.diag([0.1, 0.1, 1.0, 1.0])


def _filter(kind="ekf"):
    return make_filter(kind, WienerVelocity(0.1), Bearings(SENSORS, 0.05), X0, P0)


def _log(K=40, seed=0):
    rng = np.random.default_rng(seed)
    z = np.stack([np.linspace(1.9, 1.5, K), np.linspace(-1.9, -1.5, K)], axis=1)
    z = z + 0.05 * rng.normal(size=z.shape)
    z[5, 0] = np.nan
    z[9] = np.nan
    return z


@pytest.mark.parametrize("kind", ["ekf", "iekf", "ukf", "iplf"])
def test_run_sequence_is_the_filter_stepped_by_hand(kind):
    z, dts = _log(), np.linspace(0.01, 0.03, 40)
    out = run_sequence(_filter(kind), z, dts, record={"trace": lambda f: np.trace(f.P)})
    f = _filter(kind)
    np.testing.assert_array_equal(out.x0, f.x)
    for k in range(40):
        info = f.step(float(dts[k]), z[k])
        np.testing.assert_array_equal(out.x[k], f.x)
        np.testing.assert_array_equal(out.P[k], f.P)
        assert out.series["trace"][k] == np.trace(f.P)
        if info is None:
            assert np.isnan(out.nis[k]) and out.nis_dof[k] == 0
        else:
            assert out.nis[k] == float(info.nis) and out.nis_dof[k] == len(info.nu)
    assert out.nis_dof[5] == 1 and out.nis_dof[9] == 0


def test_run_sequence_names_the_failing_step():
    z = _log()
    z[17, 1] = np.inf
    with pytest.raises(StepError, match="step 17") as err:
        run_sequence(_filter(), z, 0.01)
    assert err.value.step == 17


def test_monte_carlo_marks_failed_runs_and_leaves_the_others_alone():
    Z = np.stack([_log(seed=s) for s in range(4)])
    Z[2, 11, 0] = np.inf
    run = monte_carlo("ekf", lambda r: _filter(), Z, 0.01)
    assert run.failed.tolist() == [False, False, True, False]
    assert np.isnan(run.x[2]).all() and np.isnan(run.P[2]).all()
    for r in (0, 1, 3):
        np.testing.assert_array_equal(run.x[r], run_sequence(_filter(), Z[r], 0.01).x)
    truth = np.zeros_like(run.x)
    rr = run_rmse(squared_error(run.x, truth, slice(0, 2)))
    assert np.isnan(rr[2]) and np.all(np.isfinite(rr[[0, 1, 3]]))
    xs, Ps = run.with_prior(0)
    assert xs.shape == (41, 4) and np.array_equal(xs[0], X0) and np.array_equal(Ps[1:], run.P[0])


def test_nis_consistency():
    """chi2(dof) samples pass (sum / sum dof inside chi2_band(1, sum dof)), twice them fail;
    steps without an update (dof 0) are ignored."""
    rng = np.random.default_rng(1)
    dof = rng.integers(0, 3, 500)
    nis = np.where(dof > 0, rng.chisquare(np.maximum(dof, 1)), np.nan)
    ok = nis_consistency(nis, dof)
    assert ok["updates"] == int((dof > 0).sum()) and ok["nis_dof_sum"] == int(dof.sum())
    assert ok["nis_per_dof_band"] == pytest.approx(list(chi2_band(1, int(dof.sum()))))
    assert ok["nis_consistent"] is True and 0.0 < ok["nis_fraction_above_upper"] < 0.06
    assert nis_consistency(2 * nis, dof)["nis_consistent"] is False
    none = nis_consistency(np.full(3, np.nan), np.zeros(3, dtype=int))
    assert none["updates"] == 0 and none["nis_per_dof"] is None


# ------------------------------------------------------------- runs stepped together

STACKED_KINDS = ["ekf", "iekf", "ukf", "ckf", "iplf", "srukf", "crukf", "ankf1", "ankf2",
                 "fuzzy-r", "fuzzy-q", "siim-ekf"]


def _runs(R=5, K=40):
    """R runs of _log's geometry with their own noise; run 1 misses cells the others
    measure (its own missing pattern: a stack of its own)."""
    Z = np.stack([_log(K, seed=s) for s in range(R)])
    Z[1, 20, 1] = np.nan
    return Z


@pytest.mark.parametrize("kind", STACKED_KINDS)
def test_a_stack_of_runs_equals_each_run_alone(kind):
    """The same filter code with a leading run axis: every run of a stack has the numbers of
    its one-track filter (to rounding), its NIS and iteration counts included; the harness
    groups the runs by their missing cells."""
    Z = _runs()
    x0s = X0 + 0.01 * np.arange(len(Z))[:, None]
    motion, meas = WienerVelocity(0.1), Bearings(SENSORS, 0.05)
    stack = monte_carlo(kind, lambda r: make_filter(kind, motion, meas, x0s[r], P0), Z, 0.01)
    assert not stack.failed.any()
    for r in range(len(Z)):
        alone = run_sequence(make_filter(kind, motion, meas, x0s[r], P0), Z[r], 0.01)
        np.testing.assert_allclose(stack.x[r], alone.x, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(stack.P[r], alone.P, rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(stack.nis[r], alone.nis, rtol=1e-9)
        np.testing.assert_array_equal(stack.nis_dof[r], alone.nis_dof)
    if kind in ("iekf", "iplf"):
        f = make_filter(kind, motion, meas, np.tile(X0, (len(Z), 1)), P0)
        f.step(0.01, Z[:, 0])
        assert f.iterations.shape == (len(Z),) and np.all(f.iterations >= 2)


def _stack_of(kind):
    """A factory of the harness: the filter of the runs `r` (an index array: a stack; an
    int: one track), all from X0."""
    x0s = np.tile(X0, (5, 1))
    return lambda r: make_filter(kind, WienerVelocity(0.1), Bearings(SENSORS, 0.05), x0s[r], P0)


def test_the_missing_patterns_group_the_runs():
    Z = _runs(R=4)
    groups = missing_patterns(Z)
    assert [g.tolist() for g in groups] == [[0, 2, 3], [1]]


def test_a_failing_run_of_a_stack_fails_alone():
    """An infinite cell in one run fails the stack; the runs are then stepped one at a time:
    only that run is marked failed and the others have their own numbers."""
    Z = _runs(R=4)
    Z[2, 11, 0] = np.inf
    run = monte_carlo("iekf", _stack_of("iekf"), Z, 0.01)
    assert run.failed.tolist() == [False, False, True, False]
    assert np.isnan(run.x[2]).all()
    for r in (0, 3):
        np.testing.assert_allclose(run.x[r], run_sequence(_filter("iekf"), Z[r], 0.01).x,
                                   rtol=1e-9, atol=1e-12)


def test_runs_one_at_a_time_gives_the_stacked_numbers(capsys):
    """batch=False (asked for: no warning) steps each run alone, to the stacked numbers."""
    Z = _runs(R=3)
    stacked = monte_carlo("iplf", _stack_of("iplf"), Z, 0.01)
    alone = monte_carlo("iplf", _stack_of("iplf"), Z, 0.01, batch=False)
    np.testing.assert_allclose(stacked.x, alone.x, rtol=1e-9, atol=1e-12)
    assert capsys.readouterr().err == ""


def test_a_failed_stack_is_reported(capsys):
    """When a stack fails, its runs are stepped again one at a time (here they all succeed
    alone) and a warning on stderr says so, with the kind, the number of runs and why: a
    researcher sees why the experiment is slow."""
    Z = _runs(R=5)                      # stacks: runs 0, 2, 3, 4 and run 1 alone

    def fails_as_a_stack(filt, k):
        if k == 5 and filt.x.ndim == 2:
            raise NotPositiveDefiniteError("S is not positive definite")

    run = monte_carlo("ekf", _stack_of("ekf"), Z, 0.01, before_step=fails_as_a_stack)
    assert not run.failed.any()
    assert capsys.readouterr().err == (
        "warning: ekf: 4 runs stepped one at a time, not as one stack (the stack failed at "
        "step 5: S is not positive definite)\n")
    for r in (0, 2):
        np.testing.assert_array_equal(run.x[r], run_sequence(_filter(), Z[r], 0.01).x)


def test_a_factory_without_stacks_is_reported(capsys):
    """A factory that builds one-track filters only (it ignores the runs it is given) is
    stepped one run at a time, and stderr says so once per stack (runs 0 and 2; run 1
    misses other cells and is a stack of one)."""
    Z = _runs(R=3)
    run = monte_carlo("ekf", lambda r: _filter(), Z, 0.01)
    assert not run.failed.any()
    assert capsys.readouterr().err == ("warning: ekf: 2 runs stepped one at a time, not as one "
                                       "stack (the factory builds no stack of runs)\n")


@pytest.mark.parametrize("kind", ["iekf", "iplf"])
def test_a_stack_with_a_constant_measurement_jacobian(kind):
    """A linear measurement model gives one H for the whole stack; the iterations still keep
    one linearisation per run (equal to each run alone)."""
    rng = np.random.default_rng(4)
    Z = rng.normal(size=(3, 20, 2))
    motion, meas = WienerVelocity(0.1), position_measurement(4, 0.5)
    x0s = X0 + 0.1 * np.arange(3)[:, None]
    stack = monte_carlo(kind, lambda r: make_filter(kind, motion, meas, x0s[r], P0), Z, 0.1)
    for r in range(3):
        alone = run_sequence(make_filter(kind, motion, meas, x0s[r], P0), Z[r], 0.1)
        np.testing.assert_allclose(stack.x[r], alone.x, rtol=1e-9, atol=1e-12)
