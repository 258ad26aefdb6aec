"""The ground truth as detections (vtrack.evaluation.oracle): which rows it keeps, the noise
and drops it adds, the ignore marking of vehicles that have not moved yet, and the share of the ground truth
it leaves."""

from __future__ import annotations

import numpy as np
import pytest

from vtrack.evaluation.mot import evaluate_arrays
from vtrack.evaluation.oracle import (hidden_crossings, moved_share, oracle_detections,
                                      unmoved_ignored)


def _row(frame: int, vid: int, x: float, y: float, w: float = 20.0, h: float = 10.0,
         conf: float = 1.0, vis: float = 1.0) -> list[float]:
    return [frame, vid, x, y, w, h, conf, -1, -1, -1, vis]


def _mover(vid: int, frames: range, x0: float, speed: float, y: float = 50.0
           ) -> list[list[float]]:
    return [_row(f, vid, x0 + speed * (f - frames.start), y) for f in frames]


def test_keeps_the_scored_rows_as_they_are() -> None:
    gt = np.array([_row(1, 1, 10, 20), _row(1, 2, 50, 20, vis=0.2), _row(2, 3, 0, 0, conf=0),
                   _row(2, 1, 12, 20, vis=0.3)])
    dets = oracle_detections(gt)
    np.testing.assert_array_equal(dets, [[1, 10, 20, 20, 10], [2, 12, 20, 20, 10]])


def test_noise_is_in_box_scales_and_drops_are_at_the_rate_asked() -> None:
    n = 20000
    gt = np.array([_row(1 + k // 10, 1 + k, 100.0, 100.0, w=40.0, h=10.0) for k in range(n)])
    dets = oracle_detections(gt, noise=0.1, rng=np.random.default_rng(1))
    x1 = dets[:, 1] + dets[:, 3]
    assert np.std(dets[:, 1] - 100.0) == pytest.approx(0.1 * 20.0, rel=0.03)  # sqrt(40 10)
    assert np.std(x1 - 140.0) == pytest.approx(2.0, rel=0.03)
    assert abs(np.mean(dets[:, 2] - 100.0)) < 0.1
    kept = oracle_detections(gt, drop=0.3, rng=np.random.default_rng(2))
    assert len(kept) / n == pytest.approx(0.7, abs=4 * np.sqrt(0.21 / n))
    with pytest.raises(ValueError):
        oracle_detections(gt, drop=1.5)


def test_unmoved_rows_are_ignored_until_the_vehicle_moves() -> None:
    standing = [_row(f, 1, 100.0 + 0.5 * (f % 2), 50.0) for f in range(1, 11)]   # jitter
    moving = _mover(1, range(11, 21), 100.0, 4.0)      # 4 px a frame; half a scale is 7 px
    parked = [_row(f, 2, 300.0, 80.0) for f in range(1, 21)]
    gt = np.array(standing + moving + parked)
    out = unmoved_ignored(gt)
    np.testing.assert_array_equal(out[:, [0, 1, 2, 3, 4, 5, 7, 8, 9, 10]],
                                  gt[:, [0, 1, 2, 3, 4, 5, 7, 8, 9, 10]])
    one = out[:20]
    # 100 + 4 k >= 100 + 7 from k = 2 on (frame 13): frames 1-12 ignored
    assert one[one[:, 0] <= 12, 6].tolist() == [0] * 12
    assert one[one[:, 0] >= 13, 6].tolist() == [1] * 8
    assert (out[20:, 6] == 0).all()                    # never moves: all ignored


def test_a_parked_vehicle_then_costs_a_motion_tracker_nothing() -> None:
    """Scored with the marking, tracks of the moving vehicle alone are perfect; a tracker
    that also follows the parked one is not charged for it either."""
    moving = _mover(1, range(1, 31), 10.0, 5.0)
    parked = [_row(f, 2, 300.0, 80.0) for f in range(1, 31)]
    gt = np.array(moving + parked)
    tracks = np.array([r[:10] for r in moving])
    both = np.array([r[:10] for r in moving + parked])
    plain = evaluate_arrays(gt, tracks)
    assert plain["misses"] == 30 and plain["mota"] < 0.6
    marked = unmoved_ignored(gt)
    first = marked[marked[:, 1] == 1]
    assert (first[:2, 6] == 0).all() and (first[2:, 6] == 1).all()   # 10 px = 0.7 scale
    for rows in (tracks, both):
        s = evaluate_arrays(marked, rows)
        assert s["mota"] == pytest.approx(1.0) and s["false_positives"] == 0


def test_moved_share_is_the_ceiling_of_a_motion_tracker() -> None:
    """30 rows of a mover (the first 2 before it has moved 0.5 scales), 30 of a parked car
    and 5 rows too hidden to score: 28 of 60 scored rows are of a vehicle once moved, and a
    tracker that follows the mover perfectly scores exactly that MOTA on the full truth."""
    moving = _mover(1, range(1, 31), 10.0, 5.0)
    parked = [_row(f, 2, 300.0, 80.0) for f in range(1, 31)]
    hidden = [_row(f, 3, 500.0, 80.0, vis=0.1) for f in range(1, 6)]
    gt = np.array(moving + parked + hidden)
    assert moved_share(gt, unmoved_ignored(gt)) == pytest.approx(28 / 60)
    tracks = np.array([r[:10] for r in moving[2:]])
    assert evaluate_arrays(gt, tracks)["mota"] == pytest.approx(28 / 60)
    assert np.isnan(moved_share(gt[:0], gt[:0]))                # nothing scored


def test_crossings_out_of_sight_on_one_side_are_hidden() -> None:
    """A vertical line at x = 100 (forward: moving left). Vehicle 1 crosses in view; 2
    crosses behind a bus and is seen on both sides; 3 crosses hidden and is never seen
    again; 4 is hidden from its first row until after the line. Only 3 and 4 are hidden,
    and each counts in its own direction."""
    line = [[100.0, 0.0, 100.0, 200.0]]
    gt = []
    for vid, speed in ((1, 10.0), (2, 10.0), (3, -10.0), (4, 10.0)):
        x0 = 40.0 if speed > 0 else 160.0
        for f in range(1, 13):
            x = x0 + speed * (f - 1) - 10            # box centre x0 + speed (f - 1)
            crossing = abs(x + 10 - 100) <= 15
            vis = {1: 1.0,
                   2: 0.0 if crossing else 1.0,
                   3: 0.0 if x + 10 <= 115 else 1.0,
                   4: 0.0 if x + 10 <= 115 else 1.0}[vid]
            gt.append(_row(f, vid, x, 30.0 * vid, vis=vis))
    gt = np.array(gt)
    assert hidden_crossings(gt, line) == [[1, 1]]
    assert hidden_crossings(gt[gt[:, 1] <= 2], line) == [[0, 0]]
    assert hidden_crossings(gt[:, :10], line) == [[0, 0]]    # no visibility column
