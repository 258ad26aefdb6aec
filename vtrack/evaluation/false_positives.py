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
"""

from __future__ import annotations

import numpy as np

from vtrack.boxes import intersection, iou
from vtrack.evaluation.mot import MATCH_IOU, drop_ignored, match_boxes

CLASSES = ("coasted", "false detection", "box off a true detection", "other")


def _matched(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a),) whether each box of a has a one-to-one match in b (`match_boxes`)."""
    out = np.zeros(len(a), dtype=bool)
    out[match_boxes(a, b)[0]] = True
    return out


def classify_false_positives(gt: np.ndarray, detections: np.ndarray, tracks: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
    """(rows, classes): the tracker rows left after the ignore regions are dropped and, per
    row, -1 where a ground-truth box matches it, else its class index into CLASSES."""
    gt, tracks = drop_ignored(gt, tracks)
    cls = np.full(len(tracks), -1)
    for frame in np.unique(tracks[:, 0]):
        ti = np.flatnonzero(tracks[:, 0] == frame)
        boxes = tracks[ti, 2:6]
        truth = gt[gt[:, 0] == frame, 2:6]
        dets = detections[detections[:, 0] == frame, 2:6]
        hit = _matched(boxes, truth)
        true_det = _matched(dets, truth)
        coasted = tracks[ti, 6] < 1.0
        false_det = (iou(boxes, dets[~true_det]) >= MATCH_IOU).any(axis=1)
        off_true = (intersection(boxes[:, None], dets[true_det][None]) > 0).any(axis=1)
        why = np.select([coasted, false_det, off_true], [0, 1, 2], 3)
        cls[ti] = np.where(hit, -1, why)
    return tracks, cls


def false_positive_counts(gt: np.ndarray, detections: np.ndarray, tracks: np.ndarray
                          ) -> dict[str, int]:
    """The number of unmatched tracker rows per class (CLASSES)."""
    _, cls = classify_false_positives(gt, detections, tracks)
    return {c: int(np.sum(cls == i)) for i, c in enumerate(CLASSES)}
