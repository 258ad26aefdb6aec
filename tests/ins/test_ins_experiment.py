"""`vtrack experiment ins`: INTERFACE.md schema, determinism and the example run."""

import json
import os

import numpy as np
import pytest

from record_golden import assert_unchanged
from tolerance import json_differences
from vtrack.experiments import ins, load_all


@pytest.fixture()
def short(monkeypatch):
    """The experiment on short scenarios so that it runs in seconds."""
    monkeypatch.setattr(ins, "HEADLINE", ins.Scenario(duration=30.0))
    monkeypatch.setattr(ins, "OUTAGE", ins.Scenario(duration=40.0, outages=((15.0, 25.0),)))
    monkeypatch.setattr(ins, "CAR", ins.Scenario(vehicle="car", duration=30.0))


def test_registered():
    assert "ins" in load_all()


@pytest.mark.golden
def test_schema_and_same_seed_same_json(short):
    a = ins.run(2, 5)
    assert_unchanged("ins", a.summary)
    b = ins.run(2, 5)
    c = ins.run(2, 6)
    ja, jb = json.dumps(a.summary, sort_keys=True), json.dumps(b.summary, sort_keys=True)
    assert ja == jb
    assert json.dumps(c.summary, sort_keys=True) != ja
    assert "NaN" not in ja and "Infinity" not in ja
    res = a.summary["results"]
    assert set(res) == {"mag", "no-mag"}
    for entry in res.values():
        for key in ("rmse", "vel_rmse", "att_rmse_deg", "heading_rmse_deg", "anees"):
            assert isinstance(entry[key], float) and np.isfinite(entry[key])
    cases = a.summary["cases"]
    assert {"nine-state", "fifteen-state", "paper-attitude", "outage", "car"} <= set(cases)
    assert set(cases["nine-state"]["results"]) == {"mag", "no-mag"}
    assert cases["nine-state"]["results"]["mag"]["anees_dof"] == 9
    assert "outages" in cases["outage"]["results"]["mag"]


def test_one_run_at_a_time_gives_the_batched_json(short):
    """run(..., batch=False) (the benchmarks' per-run loop: every run and label a batch of
    one) gives the batched JSON within the golden tests' tolerance."""
    a, b = ins.run(2, 5).summary, ins.run(2, 5, batch=False).summary
    assert not json_differences(a, b)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="worker processes need fork")
def test_the_cases_in_two_workers_give_the_json_of_one(short, monkeypatch):
    """The headline and the cases side by side (parallel.map_tasks): the very same numbers
    as one after the other in one process."""
    monkeypatch.setenv("VTRACK_WORKERS", "1")
    alone = json.dumps(ins.run(2, 5).summary)
    monkeypatch.setenv("VTRACK_WORKERS", "2")
    assert json.dumps(ins.run(2, 5).summary) == alone


def test_example_run_has_what_the_plot_needs(short):
    ex = ins.run(2, 0).example
    T = len(ex.times)
    assert ex.truth.shape == (T, 3) and ex.position == (0, 1)
    for label in ("mag", "no-mag"):
        assert ex.estimates[label].shape == (T, 3)
        assert ex.covariances[label].shape == (T, 3, 3)
        assert ex.nees[label].shape == (T,)
        assert ex.extra_series[f"rmse/{label}"].shape == (T,)
    gps = ex.extra_series["gps_fix"]
    assert gps.min() == 0.0 and gps.max() == 1.0          # the outage is visible
