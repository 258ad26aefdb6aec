"""MOT metrics on toy cases whose scores can be computed by hand."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from vtrack.errors import InputError
from vtrack.evaluation.mot import (detection_scores, evaluate, evaluate_arrays, evaluate_combined,
                                  read_mot)


def row(frame: int, ident: int, lane: int, vis: float | None = None) -> list[float]:
    """A 40x20 box moving right 2 px per frame; one lane (row band) per object."""
    values = [frame, ident, 100.0 + 2 * frame, 50.0 + 100 * lane, 40, 20, 1, -1, -1, -1]
    return values if vis is None else values + [vis]


def track(frames: range, ident: int, lane: int) -> list[list[float]]:
    return [row(f, ident, lane) for f in frames]


GT = np.array(track(range(1, 11), 1, 0) + track(range(1, 11), 2, 1))


def test_perfect_tracks_score_one():
    res = evaluate_arrays(GT, GT.copy())
    assert res["mota"] == res["idf1"] == res["hota"] == 1.0
    assert res["id_switches"] == res["false_positives"] == res["misses"] == 0
    assert (res["gt_ids"], res["pred_ids"], res["frames"]) == (2, 2, 10)


def test_one_track_fully_missed():
    res = evaluate_arrays(GT, GT[GT[:, 1] == 1])
    assert res["misses"] == 10 and res["false_positives"] == 0
    assert res["mota"] == pytest.approx(1 - 10 / 20)
    assert res["idf1"] == pytest.approx(2 * 10 / (20 + 10))
    assert res["hota"] == pytest.approx(np.sqrt(10 / 20 * 1.0))   # DetA 0.5, AssA 1


def test_id_switch():
    gt = np.array(track(range(1, 21), 1, 0))
    tracks = np.array(track(range(1, 11), 1, 0) + track(range(11, 21), 2, 0))
    res = evaluate_arrays(gt, tracks)
    assert res["id_switches"] == 1
    assert res["mota"] == pytest.approx(1 - 1 / 20)
    assert res["idf1"] == pytest.approx(2 * 10 / (20 + 20))
    # every detection is right (DetA 1); each half has A = 10 / (10 + 10 + 0) = 0.5
    assert res["hota"] == pytest.approx(np.sqrt(0.5))


def test_detection_scores_count_each_detection_once():
    """The detector's ceiling: object 1 detected in all 10 frames, object 2 in 3, one box on
    nothing, ids all -1 (as in detections.csv) -> recall 13/20, precision 13/14."""
    dets = np.array([r for r in GT if r[1] == 1] + [r for r in GT if r[1] == 2][:3]
                    + [row(1, 5, 3)])
    dets[:, 1] = -1
    res = detection_scores(GT, dets)
    assert res["recall"] == pytest.approx(13 / 20)
    assert res["precision"] == pytest.approx(13 / 14)
    assert detection_scores(GT, np.zeros((0, 10)))["recall"] == 0.0


def test_false_positives():
    ghosts = [row(f, 9, 3) for f in range(1, 6)]
    res = evaluate_arrays(GT, np.vstack([GT, ghosts]))
    assert res["false_positives"] == 5 and res["misses"] == 0
    assert res["mota"] == pytest.approx(1 - 5 / 20)
    assert res["precision"] == pytest.approx(20 / 25)


def test_combined_scores_pool_the_sequences_counts():
    """MOTChallenge's combined MOTA and IDF1 are those of the pooled counts, computed here
    from each sequence's own result: a short perfect sequence and a long one with a missed
    object and an identity switch. The mean of the two MOTAs weighs them alike; the combined
    one weighs the long sequence's 40 boxes against the short one's 20."""
    long_gt = np.array(track(range(1, 21), 1, 0) + track(range(1, 21), 2, 1))
    long_tr = np.array(track(range(1, 11), 1, 0) + track(range(11, 21), 3, 0))
    seqs = [(GT, GT.copy()), (long_gt, long_tr)]
    each = [evaluate_arrays(g, t) for g, t in seqs]
    comb = evaluate_combined(seqs)
    errors = sum(r["misses"] + r["false_positives"] + r["id_switches"] for r in each)
    boxes = sum(r["gt_boxes"] for r in each)
    assert (each[1]["misses"], each[1]["id_switches"]) == (20, 1)
    assert comb["mota"] == pytest.approx(1 - errors / boxes)          # 1 - 21 / 60
    assert comb["mota"] != pytest.approx(np.mean([r["mota"] for r in each]))
    idtp = sum(r["idf1"] * (r["gt_boxes"] + r["pred_boxes"]) / 2 for r in each)
    assert comb["idf1"] == pytest.approx(2 * idtp / (boxes + sum(r["pred_boxes"] for r in each)))
    assert min(r["hota"] for r in each) < comb["hota"] < max(r["hota"] for r in each)
    assert (comb["gt_boxes"], comb["pred_boxes"]) == (60, 40)
    one = evaluate_combined(seqs[1:])
    assert {k: one[k] for k in ("mota", "idf1", "hota")} == \
        {k: each[1][k] for k in ("mota", "idf1", "hota")}
    with pytest.raises(ValueError):
        evaluate_combined([])


def test_empty_tracks_are_all_misses():
    res = evaluate_arrays(GT, np.zeros((0, 10)))
    assert res["misses"] == 20 and res["mota"] == 0 and res["hota"] == 0


def test_tracker_box_on_ignore_region_is_neither_hit_nor_false_positive():
    vis = [1.0] * 10
    hidden = [0.2 if 3 <= f <= 6 else 1.0 for f in range(1, 11)]
    gt = np.array([row(f, 1, 0, v) for f, v in zip(range(1, 11), vis)]
                  + [row(f, 2, 1, v) for f, v in zip(range(1, 11), hidden)])
    with_boxes = evaluate_arrays(gt, GT.copy())
    without = evaluate_arrays(gt, GT[~((GT[:, 1] == 2) & (GT[:, 0] >= 3) & (GT[:, 0] <= 6))])
    assert with_boxes["ignored_gt_boxes"] == 4 and with_boxes["ignored_pred_boxes"] == 4
    assert with_boxes["false_positives"] == 0 and with_boxes["misses"] == 0
    assert with_boxes["true_positives"] == 16
    for key in ("mota", "idf1", "hota", "id_switches", "false_positives", "misses"):
        assert with_boxes[key] == without[key], key
    # a tracker box that does not overlap the ignore region is still a false positive
    stray = evaluate_arrays(gt, np.vstack([GT, [row(4, 7, 3)]]))
    assert stray["false_positives"] == 1


def test_conf_zero_ground_truth_is_an_ignore_region():
    gt = GT.copy()
    gt[gt[:, 1] == 2, 6] = 0
    res = evaluate_arrays(gt, GT.copy())
    assert res["mota"] == 1.0 and res["false_positives"] == 0 and res["gt_boxes"] == 10


def test_anchor_sanity_case_two_cars_swap_ids_at_frame_35():
    """ANCHORS.md section 5: 2 cars x 50 frames, 4 missed detections, both tracks switch
    ids at frame 35 -> MOTA 0.94, IDSW 2, IDF1 0.653. Here the ids swap (track 1 follows
    car 2 from frame 35) and the 4 misses fall in frames 5-6, so with exact boxes DetA = 0.96
    and AssA can be counted by hand. (The anchor's HOTA 0.643 needs its noisy boxes.)"""
    gt = np.array(track(range(1, 51), 1, 0) + track(range(1, 51), 2, 1))
    missed = {(5, 1), (6, 1), (5, 2), (6, 2)}
    tracks = np.array([row(f, c if f < 35 else 3 - c, c - 1) for f in range(1, 51)
                       for c in (1, 2) if (f, c) not in missed])
    res = evaluate_arrays(gt, tracks)
    assert res["id_switches"] == 2 and res["misses"] == 4 and res["false_positives"] == 0
    assert res["mota"] == pytest.approx(0.94)
    # best id pairing keeps frames 1-34 minus the 2 misses per car: IDTP = 64
    assert res["idf1"] == pytest.approx(2 * 64 / (100 + 96)) and round(res["idf1"], 3) == 0.653
    # per car: 32 TPs with A = 32 / (32 + 18 + 16), 16 TPs with A = 16 / (16 + 34 + 32)
    assa = 2 * (32 * 32 / 66 + 16 * 16 / 82) / 96
    assert res["hota"] == pytest.approx(np.sqrt(0.96 * assa), abs=1e-3)


def test_read_mot_round_trip_and_empty_file(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("1,3,10.5,20,30,40,1,-1,-1,-1\n\n2, 3, 11,20,30,40,0.5,-1,-1,-1\n")
    data = read_mot(path)
    assert data.shape == (2, 10) and data[1, 6] == 0.5
    (tmp_path / "empty.csv").write_text("")
    assert read_mot(tmp_path / "empty.csv").shape == (0, 10)


@pytest.mark.parametrize("text, where", [
    ("1,1,0,0,10,10,1,-1,-1\n", "line 1"),
    ("1,1,0,0,10,10,1,-1,-1,-1\n1,2,0,0,10,10,1,-1,-1,-1,1\n", "line 2"),
    ("1,1,0,0,10,10,1,-1,-1,-1\n2,1,zero,0,10,10,1,-1,-1,-1\n", "line 2"),
    ("1,1,0,0,nan,10,1,-1,-1,-1\n", "line 1"),
    ("0,1,0,0,10,10,1,-1,-1,-1\n", "line 1"),
    ("1,1.5,0,0,10,10,1,-1,-1,-1\n", "line 1"),
    ("1,1,0,0,-10,10,1,-1,-1,-1\n", "line 1"),
    ("1,1,0,0,10,10,1,-1,-1,-1\n1,2,0,0,10,10,1,-1,-1,-1\n1,1,5,0,10,10,1,-1,-1,-1\n",
     "line 3"),
])
def test_bad_rows_name_file_and_line(tmp_path, text, where):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=rf"bad\.csv: {where}:"):
        read_mot(path)


def test_missing_and_empty_ground_truth(tmp_path):
    good = tmp_path / "t.csv"
    good.write_text("1,1,0,0,10,10,1,-1,-1,-1\n")
    with pytest.raises(InputError, match="nope.csv: no such file"):
        evaluate(tmp_path / "nope.csv", good)
    (tmp_path / "gt.csv").write_text("\n")
    with pytest.raises(InputError, match="gt.csv: no ground-truth rows"):
        evaluate(tmp_path / "gt.csv", good)


def test_missing_trackeval_names_the_pip_command(monkeypatch):
    monkeypatch.setitem(sys.modules, "trackeval", None)
    with pytest.raises(InputError, match=r"pip install --no-deps trackeval==1\.3\.0 tabulate"):
        evaluate_arrays(GT, GT.copy())
