"""Outputs of the filter kinds and experiments that existed before the estimation refactor
(filter registry, Q/R hooks, Monte Carlo harness, adaptive/ins subpackages) are unchanged,
bit for bit: `vtrack filter` ESTIMATES.csv for every kind on several models and logs (with
missing cells), and `vtrack experiment NAME --json` of every experiment on the shrunk
settings of its own tests. The expected files were recorded from the code before the
refactor by tests/golden/record_golden.py (see its docstring); new keys (new filter kinds,
new cases) may be added, nothing recorded may change.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

GOLDEN = Path(__file__).resolve().parents[1] / "golden"
sys.path.insert(0, str(GOLDEN))
import record_golden as rg  # noqa: E402

EXPECTED = json.loads((GOLDEN / "filter" / "expected.json").read_text())


@pytest.mark.parametrize("case", rg.CASES, ids=[rg.case_key(*c) for c in rg.CASES])
def test_filter_estimates_unchanged(tmp_path, capsys, case):
    got = rg.run_filter_case(GOLDEN / "filter", tmp_path, *case)
    want = EXPECTED[rg.case_key(*case)]
    assert got["code"] == want["code"]
    if want["code"]:
        assert got["error"] == want["error"]
        return
    assert got["rows"] == want["rows"]
    assert got["sampled"] == want["sampled"]      # first a readable diff, then every byte
    assert got["sha256"] == want["sha256"]


@pytest.mark.parametrize("name", sorted(rg.SHRINK))
def test_experiment_json_unchanged(name):
    _, _, runs, seed = rg.SHRINK[name]
    with rg.shrunk(name):
        got = rg.experiment_json(name, runs, seed)
    want = json.loads((GOLDEN / "experiments" / f"{name}.json").read_text())
    diff = rg.missing_or_changed(want, got)
    assert not diff, "\n".join(diff[:20])
