"""Outputs of the filter kinds that existed before the estimation refactor (filter registry,
Q/R hooks, Monte Carlo harness, adaptive/ins subpackages) are unchanged, bit for bit:
`vtrack filter` ESTIMATES.csv for every kind on several models and logs (with missing
cells). The expected files were recorded from the code before the refactor by
tests/golden/record_golden.py (see its docstring). The experiments' JSON is compared the
same way by each experiment's JSON test (record_golden.assert_unchanged), and at full size
by tests/golden/check_outputs.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import record_golden as rg  # tests/golden, on the path through conftest.py

GOLDEN = Path(__file__).resolve().parents[1] / "golden"

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
