"""scripts/eval_suite.py's second table: the scores with the vehicles that never moved as
ignore regions, their means, and the share of the ground truth a motion detector can see."""

from __future__ import annotations

import pytest


def _result(suite, clip: str, share: float, vtrack: float, sort: float):
    r = suite.Result(clip, "synthetic")
    r.detector = {"recall": 0.5, "moved_share": share, "recall_moved": share - 0.1}
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
    assert summary["detector"]["recall_moved_mean"] == pytest.approx(0.5)
    assert summary["detector"]["recall_moved_worst"] == pytest.approx(0.3)
    suite.print_moved(results, ["vtrack", "sort"], summary)
    lines = capsys.readouterr().out.splitlines()
    side = next(line for line in lines if line.startswith("side-0"))
    assert side.split()[1:] == ["0.400", "0.300", "0.100", "/", "0.600", "/", "0.500",
                                "0.000", "/", "0.600", "/", "0.500"]
    assert next(line for line in lines if line.startswith("mean")).split()[1:3] == [
        "0.600", "0.500"]


def test_moved_visible_ignores_unmoved_and_mostly_hidden_rows() -> None:
    """oracle.moved_visible: a vehicle's rows before it moves half a box scale, and rows
    under 70 % visible, become ignore regions (conf 0); the rest keep their conf."""
    import numpy as np

    from vtrack.evaluation.oracle import moved_visible

    rows = [[n, 1, 10.0 + 4 * max(n - 3, 0), 10, 20, 20, 1, -1, -1, -1,
             0.5 if n == 8 else 1.0] for n in range(1, 10)]
    out = moved_visible(np.array(rows))
    # centre moves 4 px a frame from frame 4: half of sqrt(20 * 20) = 10 px by frame 6
    assert out[:, 6].tolist() == [0, 0, 0, 0, 0, 1, 1, 0, 1]


def test_counts_beside_the_crossings_made_out_of_sight(load_script, capsys) -> None:
    """The synthetic count table shows each line-direction's hidden crossings
    (oracle.hidden_crossings) beside the true count, and the exact counts' ceiling."""
    suite = load_script("eval_suite")
    r = suite.Result("side-2", "synthetic")
    r.hand = [["0.60 H", [0, 0], [0, 0]], ["0.50 W", [9, 9], [7, 7]]]
    r.hidden = [[0, 0], [0, 1]]
    r.counts = {"vtrack": [[0, 0], [8, 6]]}
    summary = suite.summarise([r], ["vtrack"])
    assert summary["synth_counts_ceiling"] == {"line_directions": 4, "with_hidden_crossing": 1,
                                               "hidden_crossings": 1}
    suite.print_counts([r], ["vtrack"], summary, "synthetic clip", "true", "synth_counts",
                       "synth_count")
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["synthetic", "clip", "line", "dir", "true", "hidden", "vtrack"]
    assert lines[2].split() == ["side-2", "0.50", "W", "bwd", "7", "1", "6", "(-1)"]
    assert "1 of 4 line-directions hold one, so at most 3 counts" in " ".join(lines)
