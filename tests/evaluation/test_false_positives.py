"""The causes and the shapes of a tracker's false positives
(vtrack/evaluation/false_positives.py)."""

import numpy as np

from vtrack.evaluation.false_positives import (CLASSES, SHAPES, classify_false_positives,
                                               false_positive_counts, false_positive_shapes,
                                               shape_of_false_positives)


def gt_rows(frame, boxes, vis=None):
    return np.array([[frame, k + 1, *b, 1, 1, -1, -1, 1.0 if vis is None else vis[k]]
                     for k, b in enumerate(boxes)], dtype=float)


def track_rows(frame, boxes, conf):
    return np.array([[frame, k + 1, *b, c, -1, -1, -1]
                     for k, (b, c) in enumerate(zip(boxes, conf))], dtype=float)


def test_each_cause():
    gt = gt_rows(1, [(0, 0, 20, 20), (100, 0, 20, 20), (300, 0, 20, 20)])
    dets = track_rows(1, [(0, 0, 20, 20), (100, 0, 20, 20), (200, 0, 20, 20)], [1, 1, 1])
    tracks = track_rows(1, [(0, 0, 20, 20),        # right
                            (95, 0, 60, 30),       # too big, over a right detection
                            (200, 0, 20, 20),      # a false detection passed on
                            (400, 0, 20, 20),      # coasted over nothing
                            (500, 0, 20, 20)],     # detected row, no detection near: other
                        [1, 1, 1, 0.5, 1])
    _, cls = classify_false_positives(gt, dets, tracks)
    names = [CLASSES[c] if c >= 0 else "matched" for c in cls]
    assert names == ["matched", "box off a true detection", "false detection", "coasted",
                     "other"]


def test_rows_on_ignored_ground_truth_are_not_counted():
    gt = gt_rows(1, [(0, 0, 20, 20), (100, 0, 20, 20)], vis=[1.0, 0.1])
    dets = track_rows(1, [(100, 0, 20, 20)], [1])
    tracks = track_rows(1, [(100, 0, 20, 20)], [1])
    assert sum(false_positive_counts(gt, dets, tracks).values()) == 0


def test_the_causes_add_up_to_trackeval_false_positives():
    """Against an independent count: trackeval's CLEAR false positives (each row its own
    identity, so no frame-to-frame continuity enters the matching)."""
    from vtrack.evaluation.mot import evaluate_arrays

    rng = np.random.default_rng(3)
    gt = np.vstack([gt_rows(f, [(*xy, 30, 20) for xy in rng.uniform(0, 200, (6, 2))])
                    for f in range(1, 9)])
    gt[:, 1] = np.arange(1, len(gt) + 1)
    tracks = np.vstack([track_rows(f, [(*xy, 30, 20) for xy in rng.uniform(0, 200, (6, 2))],
                                   rng.choice([1.0, 0.6], 6)) for f in range(1, 9)])
    tracks[:, 1] = np.arange(1, len(tracks) + 1)
    counts = false_positive_counts(gt, tracks[tracks[:, 6] == 1], tracks)
    fp = evaluate_arrays(gt, tracks)["false_positives"]
    assert 0 < fp < len(tracks)
    assert sum(counts.values()) == fp


def test_each_shape():
    gt = gt_rows(1, [(0, 0, 20, 20), (22, 0, 20, 20), (100, 0, 40, 20), (200, 0, 40, 40),
                     (300, 0, 20, 20)])
    tracks = track_rows(1, [(0, 0, 42, 20),       # both cars at 0 and 22: a merge
                            (95, -5, 60, 35),     # around the car at 100, far too large
                            (205, 5, 15, 15),     # a piece inside the van at 200
                            (300, 0, 20, 20),     # right
                            (500, 0, 20, 20),     # on the road
                            (310, 10, 20, 20)],   # a quarter on the car at 300: elsewhere
                        [1, 1, 1, 1, 1, 1])
    _, shapes = shape_of_false_positives(gt, tracks)
    names = [SHAPES[c] if c >= 0 else "matched" for c in shapes]
    assert names == ["several", "around one", "inside one", "matched", "elsewhere",
                     "elsewhere"]


def test_the_shapes_add_up_to_trackeval_false_positives():
    from vtrack.evaluation.mot import evaluate_arrays

    rng = np.random.default_rng(5)
    gt = np.vstack([gt_rows(f, [(*xy, 30, 20) for xy in rng.uniform(0, 200, (6, 2))])
                    for f in range(1, 9)])
    gt[:, 1] = np.arange(1, len(gt) + 1)
    tracks = np.vstack([track_rows(f, [(*xy, *wh) for xy, wh in
                                       zip(rng.uniform(0, 200, (6, 2)),
                                           rng.uniform(10, 70, (6, 2)))], [1.0] * 6)
                        for f in range(1, 9)])
    tracks[:, 1] = np.arange(1, len(tracks) + 1)
    shapes = false_positive_shapes(gt, tracks)
    fp = evaluate_arrays(gt, tracks)["false_positives"]
    assert 0 < fp < len(tracks)
    assert sum(shapes.values()) == fp
    assert all(shapes[c] > 0 for c in SHAPES)
