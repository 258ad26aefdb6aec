"""scripts/eval_suite.py's second table: the scores with the vehicles that never moved as
ignore regions, their means, and the share of the ground truth a motion detector can see."""

from __future__ import annotations

import pytest


def _result(suite, clip: str, share: float, vtrack: float, sort: float):
    r = suite.Result(clip, "synthetic")
    r.detector = {"recall": 0.5, "moved_share": share}
    for name, mota in (("vtrack", vtrack), ("sort", sort)):
        r.scores[name] = {m: 0.0 for m in suite.METRICS} | {
            "mota": mota, "moved": {"mota": mota + 0.1, "idf1": 0.6, "hota": 0.5}}
    return r


def test_moved_scores_are_averaged_and_printed(load_script, capsys) -> None:
    suite = load_script("eval_suite")
    results = [_result(suite, "mast-0", 0.8, 0.2, 0.3), _result(suite, "side-0", 0.4, 0.0, -0.1)]
    summary = suite.summarise(results, ["vtrack", "sort"])
    assert summary["vtrack"]["moved"]["mota_mean"] == pytest.approx(0.2)
    assert summary["vtrack"]["moved"]["mota_worst"] == pytest.approx(0.1)
    assert summary["sort"]["moved"]["mota_mean"] == pytest.approx(0.2)
    assert summary["detector"]["moved_share_mean"] == pytest.approx(0.6)
    suite.print_moved(results, ["vtrack", "sort"], summary)
    lines = capsys.readouterr().out.splitlines()
    side = next(line for line in lines if line.startswith("side-0"))
    assert side.split()[1:] == ["0.400", "0.100", "/", "0.600", "/", "0.500",
                                "0.000", "/", "0.600", "/", "0.500"]
    assert next(line for line in lines if line.startswith("mean")).split()[1] == "0.600"
