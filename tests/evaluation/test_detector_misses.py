"""The detector-miss classes of the scene suite (vtrack/evaluation/detector_misses.py)."""

import numpy as np
import pytest

from vtrack.evaluation.detector_misses import CLASSES, classify_misses, gt_speed, miss_table


def rows(frame, boxes, vis=None):
    """MOT rows (frame, id, x, y, w, h, conf, class, -1, -1, visible) of boxes in one frame."""
    out = []
    for k, b in enumerate(boxes):
        out.append([frame, k + 1, *b, 1, 1, -1, -1, 1.0 if vis is None else vis[k]])
    return np.array(out, dtype=float)


def test_each_class_from_the_detection_that_covers_most():
    gt = rows(1, [(0, 0, 20, 20),        # detected as itself
                  (100, 0, 20, 20),      # nothing there
                  (200, 0, 20, 20),      # inside a blob 4x its area (with a neighbour)
                  (300, 0, 40, 40),      # only its front 40 %
                  (400, 0, 20, 20),      # right size, half a box off
                  (500, 0, 20, 20)],     # hidden: ignored
              vis=[1, 1, 1, 1, 1, 0.1])
    dets = rows(1, [(1, 1, 20, 20), (200, 0, 40, 40), (300, 0, 16, 40), (410, 6, 20, 20)])
    got = [CLASSES[c] if c >= 0 else "ignored" for c in classify_misses(gt, dets)]
    assert got == ["matched", "none", "merged", "fragment", "offset", "ignored"]


def test_one_detection_matches_one_box_only():
    gt = rows(1, [(0, 0, 20, 20), (2, 0, 20, 20)])
    dets = rows(1, [(1, 0, 20, 20)])
    cls = [CLASSES[c] for c in classify_misses(gt, dets)]
    assert sorted(cls) == ["matched", "offset"]


def test_frames_without_detections_are_misses():
    gt = np.vstack([rows(1, [(0, 0, 20, 20)]), rows(2, [(5, 0, 20, 20)])])
    dets = rows(1, [(0, 0, 20, 20)])
    assert [CLASSES[c] for c in classify_misses(gt, dets)] == ["matched", "none"]


def test_speed_is_the_centre_displacement_per_frame():
    track = np.vstack([rows(f, [(3.0 * f, 4.0 * f, 10, 10)]) for f in range(1, 8)])
    standing = np.vstack([rows(f, [(100, 100, 10, 10)]) for f in range(1, 8)])
    standing[:, 1] = 2
    speed = gt_speed(np.vstack([track, standing]))
    assert speed[:7] == pytest.approx(5.0)
    assert speed[7:] == pytest.approx(0.0)


def test_table_bands_the_unseen_boxes_by_size_and_speed():
    small = np.vstack([rows(f, [(10.0 * f, 0, 10, 10)]) for f in range(1, 11)])
    big = np.vstack([rows(f, [(0, 200, 60, 40)]) for f in range(1, 11)])
    big[:, 1] = 2
    gt = np.vstack([small, big])
    dets = np.vstack([rows(f, [(0, 200, 60, 40)]) for f in range(1, 11)])   # the big one only
    t = miss_table(gt, dets)
    assert t["rows"] == 20
    assert t["shares"]["matched"] == pytest.approx(0.5)
    assert t["shares"]["none"] == pytest.approx(0.5)
    assert t["none_by_side_speed"]["0-15"]["2-inf"] == [10, 1.0]       # small, moving: unseen
    assert t["none_by_side_speed"]["30-inf"]["0-0.5"] == [10, 0.0]     # big, standing: seen
