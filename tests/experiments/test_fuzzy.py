"""The `fuzzy` experiment (seed 003: KF vs fuzzy-r / fuzzy-q)."""

import json

import pytest

from record_golden import assert_unchanged
from vtrack.experiments import fuzzy as fz


# --------------------------------------------------------------------------- experiment


def test_fuzzy_r_beats_the_kf_when_r_is_wrong():
    """E1 (filter R = 25 I, truth 100 I): paired per-run RMSE difference KF - fuzzy-r is
    positive by more than 3 standard errors; it does not beat the model-matched KF."""
    body, _ = fz.run_case(fz.HEADLINE, 8, seed=1)
    d = body["results"]["fuzzy-r"]["rmse_minus_kf"]
    assert d["mean"] + 3 * d["se"] < 0, d
    m = body["results"]["fuzzy-r"]["rmse_minus_matched"]
    assert m["mean"] + 3 * m["se"] > 0, m


@pytest.fixture
def small_fuzzy(monkeypatch):
    monkeypatch.setattr(fz, "STEPS", 120)
    monkeypatch.setattr(fz, "CASES", {"E3": fz.CASES["E3"]})


@pytest.mark.golden
def test_json_schema_and_determinism(small_fuzzy, cli_stdout):
    out1 = cli_stdout(["experiment", "fuzzy", "--runs", "3", "--seed", "4", "--json"])
    out2 = cli_stdout(["experiment", "fuzzy", "--runs", "3", "--seed", "4", "--json"])
    assert out1 == out2
    data = json.loads(out1)
    assert_unchanged("fuzzy", data)
    assert set(data["results"]) == {"kf", "fuzzy-r", "fuzzy-q"}
    for entry in list(data["results"].values()) + list(data["cases"]["E3"]["results"].values()):
        assert isinstance(entry["rmse"], float) and entry["rmse"] > 0
        assert isinstance(entry["anees"], float)
        for axis in "xyz":
            assert entry[f"rmse_{axis}"] > 0
    assert "paper" in data["results"]["fuzzy-r"]
    out3 = cli_stdout(["experiment", "fuzzy", "--runs", "3", "--seed", "5", "--json"])
    assert out3 != out1
