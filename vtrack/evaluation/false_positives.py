"""Where a tracker's false positives come from: each row of a tracks file (MOT columns, conf
1 for a detected row and < 1 for a coasted one, as vtrack writes them) that no visible
ground-truth box matches one to one at IoU >= 0.5 (ignore regions dropped first, as
`evaluate` does) is put in one class:

- ``coasted``: a row without a detection (conf < 1): a prediction that went wrong;
- ``false detection``: the row is a detection (IoU >= 0.5 with a raw detection of that
  frame) that matches no ground truth: any tracker fed these detections shows it, unless
  it keeps the track unconfirmed;
- ``box off a true detection``: the row overlaps a detection that matches the ground truth
  while the row itself does not: the tracker's box (its size, its centre) is wrong where
  the detector was right;
- ``other``: the rest (a box over background, or over a vehicle that no detection matches).

Matching is per frame and one to one (Hungarian on IoU), so on rows that each carry their
own identity the four classes add up to trackeval's CLEAR false positives (tested).

The same rows are also put in one of SHAPES by where the box lies on the ground truth of
its frame, whatever made it (`false_positive_shapes`):

- ``several``: it holds at least half of each of two or more vehicles (a merge);
- ``around one``: it holds at least half of one vehicle, and is too large or off for IoU
  0.5 (a vehicle with its shadow or a neighbour's piece, a box that lags the size);
- ``inside one``: it holds no vehicle by half, and lies at least INSIDE on one vehicle (a
  piece of a vehicle the detector sees in parts, or whose rest melted into the background);
- ``elsewhere``: the rest (on the road, or overlapping vehicles by less).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vtrack.boxes import intersection, iou
from vtrack.evaluation.mot import MATCH_IOU, detected, drop_ignored

CLASSES = ("coasted", "false detection", "box off a true detection", "other")
SHAPES = ("several", "around one", "inside one", "elsewhere")
HELD = 0.5     # a vehicle this much inside a box is held by it
INSIDE = 0.7   # a box this much on one vehicle is a piece of it


def _unmatched_rows(gt: np.ndarray, tracks: np.ndarray,
                    judge: Callable[[np.ndarray, np.ndarray, float], np.ndarray]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(rows, labels): the tracker rows left after the ignore regions are dropped and, per
    row, -1 where a ground-truth box matches it one to one, else what
    judge(rows, truth, frame) gives it (the frame's rows and visible ground-truth boxes)."""
    gt, tracks = drop_ignored(gt, tracks)
    labels = np.full(len(tracks), -1)
    for frame in np.unique(tracks[:, 0]):
        ti = np.flatnonzero(tracks[:, 0] == frame)
        truth = gt[gt[:, 0] == frame, 2:6]
        labels[ti] = np.where(detected(tracks[ti, 2:6], truth), -1,
                              judge(tracks[ti], truth, frame))
    return tracks, labels


def classify_false_positives(gt: np.ndarray, detections: np.ndarray, tracks: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
    """(rows, classes): the tracker rows left after the ignore regions are dropped and, per
    row, -1 where a ground-truth box matches it, else its class index into CLASSES."""

    def cause(rows: np.ndarray, truth: np.ndarray, frame: float) -> np.ndarray:
        boxes = rows[:, 2:6]
        dets = detections[detections[:, 0] == frame, 2:6]
        true_det = detected(dets, truth)
        coasted = rows[:, 6] < 1.0
        false_det = (iou(boxes, dets[~true_det]) >= MATCH_IOU).any(axis=1)
        off_true = (intersection(boxes[:, None], dets[true_det][None]) > 0).any(axis=1)
        return np.select([coasted, false_det, off_true], [0, 1, 2], 3)

    return _unmatched_rows(gt, tracks, cause)


def false_positive_counts(gt: np.ndarray, detections: np.ndarray, tracks: np.ndarray
                          ) -> dict[str, int]:
    """The number of unmatched tracker rows per class (CLASSES)."""
    _, cls = classify_false_positives(gt, detections, tracks)
    return {c: int(np.sum(cls == i)) for i, c in enumerate(CLASSES)}


def shape_of_false_positives(gt: np.ndarray, tracks: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
    """(rows, shapes): the tracker rows left after the ignore regions are dropped and, per
    row, -1 where a ground-truth box matches it, else its index into SHAPES (module
    docstring)."""

    def shape(rows: np.ndarray, truth: np.ndarray, frame: float) -> np.ndarray:
        boxes = rows[:, 2:6]
        inter = intersection(boxes[:, None], truth[None])            # (rows, vehicles)
        held = (inter / np.maximum(truth[:, 2] * truth[:, 3], 1e-9) >= HELD).sum(axis=1)
        on_one = (inter / np.maximum(boxes[:, 2:3] * boxes[:, 3:4], 1e-9)).max(
            axis=1, initial=0.0)
        return np.select([held >= 2, held == 1, on_one >= INSIDE], [0, 1, 2], 3)

    return _unmatched_rows(gt, tracks, shape)


def false_positive_shapes(gt: np.ndarray, tracks: np.ndarray) -> dict[str, int]:
    """The number of unmatched tracker rows per shape (SHAPES)."""
    _, shape = shape_of_false_positives(gt, tracks)
    return {c: int(np.sum(shape == i)) for i, c in enumerate(SHAPES)}
