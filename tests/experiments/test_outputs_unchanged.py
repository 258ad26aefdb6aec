"""Outputs of the filter kinds that existed before the estimation refactor (filter registry,
Q/R hooks, Monte Carlo harness, adaptive/ins subpackages) are unchanged: `vtrack filter`
ESTIMATES.csv for every kind on several models and logs (with missing cells), every row.
The expected files were recorded from the code before the refactor by
tests/golden/record_golden.py (see its docstring). The experiments' JSON is compared the
same way by each experiment's JSON test (record_golden.assert_unchanged), and at full size
by tests/golden/check_outputs.py.

Compared within a tolerance, not bit for bit (tests/golden/tolerance.py says why and
measures it): a float agrees within 1e-9 relative to its quantity's magnitude (a state's
standard deviation, a covariance's sqrt(P_ii P_jj), the value itself if larger), since
other processors' BLAS and NumPy kernels move these outputs by at most 1.3e-12 of it
(measured with four other OpenBLAS kernels and with NumPy's AVX loops off). The exit code,
error text, row and cell counts and the header compare exactly; the rows of a filter that
diverges (the cube-root UKF on the bearings logs) only in shape once it has. The last tests
show that the comparison still bites: one recorded value altered by 1e-6 fails, by 1e-14
passes (and fails when compared exactly).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
import record_golden as rg  # tests/golden, on the path through conftest.py
import tolerance

pytestmark = pytest.mark.golden

GOLDEN = Path(__file__).resolve().parents[1] / "golden"

EXPECTED = json.loads((GOLDEN / "filter" / "expected.json").read_text())
ESTIMATES = rg.read_estimates(GOLDEN / "filter" / rg.ESTIMATES)


def assert_case_unchanged(got: dict[str, object], text: str | None, want: dict[str, object],
                          want_text: str | None, key: str) -> None:
    """One filter case's run against its recording (the code, error and row count
    exactly, then every row of ESTIMATES.csv through tolerance.estimates_differences)."""
    assert got["code"] == want["code"]
    if want["code"]:
        assert got["error"] == want["error"]
        return
    assert got["rows"] == want["rows"]
    diff = tolerance.estimates_differences(want_text, text, key)
    assert not diff, "\n".join(diff[:20])


@pytest.mark.parametrize("case", rg.CASES, ids=[rg.case_key(*c) for c in rg.CASES])
def test_filter_estimates_unchanged(tmp_path, capsys, case):
    key = rg.case_key(*case)
    got, text = rg.run_filter_case(GOLDEN / "filter", tmp_path, *case)
    assert_case_unchanged(got, text, EXPECTED[key], ESTIMATES.get(key), key)


def test_whole_estimates_are_the_recorded_bytes():
    """filter/estimates.json.gz holds, for every case that exits 0, the very ESTIMATES.csv
    whose SHA-256, row count and sampled rows expected.json recorded."""
    assert set(ESTIMATES) == {k for k, v in EXPECTED.items() if v["code"] == 0}
    for key, text in ESTIMATES.items():
        rows = text.splitlines()
        assert hashlib.sha256(text.encode()).hexdigest() == EXPECTED[key]["sha256"], key
        assert len(rows) == EXPECTED[key]["rows"], key
        assert {str(i): rows[i] for i in range(0, len(rows), 25)} == EXPECTED[key]["sampled"]


def _altered_csv(text: str, row: int, column: int, rel: float) -> str:
    """CSV text with one cell's value multiplied by 1 + rel (written back with repr)."""
    rows = [r.split(",") for r in text.splitlines()]
    rows[row][column] = repr(float(rows[row][column]) * (1 + rel))
    return "".join(",".join(r) + "\n" for r in rows)


def _altered_json(data: dict, path: tuple[str, ...], rel: float) -> dict:
    """A deep copy of JSON `data` with the float at `path` multiplied by 1 + rel."""
    out = json.loads(json.dumps(data))
    node = out
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] *= 1 + rel
    return out


ALTERED = ("linear", "kf", "", "linear")     # a fast case; x0 of its middle row is altered


@pytest.mark.parametrize(("rel", "fails"), [(1e-6, True), (1e-14, False)])
def test_an_altered_filter_golden(tmp_path, capsys, rel, fails):
    key = rg.case_key(*ALTERED)
    want_text = ESTIMATES[key]
    row = len(want_text.splitlines()) // 2
    altered = _altered_csv(want_text, row, 1, rel)
    assert altered != want_text
    got, text = rg.run_filter_case(GOLDEN / "filter", tmp_path, *ALTERED)
    if fails:
        with pytest.raises(AssertionError, match=f"row {row} column x0"):
            assert_case_unchanged(got, text, EXPECTED[key], altered, key)
    else:
        assert_case_unchanged(got, text, EXPECTED[key], altered, key)


INS_ANEES = ("results", "mag", "anees")      # in experiments/ins.json


@pytest.mark.parametrize(("rel", "fails"), [(1e-6, True), (1e-14, False)])
def test_an_altered_experiment_golden(tmp_path, monkeypatch, rel, fails):
    """assert_unchanged on a copy of experiments/ins.json with its headline ANEES altered;
    the recording itself stands in for the experiment's output (running it is the INS
    test's job)."""
    recorded = json.loads((GOLDEN / "experiments" / "ins.json").read_text())
    (tmp_path / "experiments").mkdir()
    (tmp_path / "experiments" / "ins.json").write_text(
        json.dumps(_altered_json(recorded, INS_ANEES, rel)))
    monkeypatch.setattr(rg, "HERE", tmp_path)
    if fails:
        with pytest.raises(AssertionError, match="/results/mag/anees"):
            rg.assert_unchanged("ins", recorded)
    else:
        rg.assert_unchanged("ins", recorded)


def test_exact_comparison_rejects_what_the_tolerance_accepts():
    """The 1e-14 alterations above are real changes of the bits: compared exactly (rtol 0)
    they fail, as another processor's outputs did before the tolerance."""
    key = rg.case_key(*ALTERED)
    want_text = ESTIMATES[key]
    altered = _altered_csv(want_text, len(want_text.splitlines()) // 2, 1, 1e-14)
    assert tolerance.estimates_differences(altered, want_text, rtol=0.0)
    assert not tolerance.estimates_differences(altered, want_text)
    recorded = json.loads((GOLDEN / "experiments" / "ins.json").read_text())
    altered_json = _altered_json(recorded, INS_ANEES, 1e-14)
    assert tolerance.json_differences(altered_json, recorded, rtol=0.0)
    assert not tolerance.json_differences(altered_json, recorded)
