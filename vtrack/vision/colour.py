"""The colour of a detected box, a cue that tells one vehicle from another (the tracker's
re-identification, tracking/reidentifier.py).

A box's signature is the normalised HSV histogram of its inner part (SHRINK of each side
left out: road and neighbours at the edges), BINS = hue x saturation x value bins. Two
signatures compare by their Bhattacharyya coefficient sum(sqrt(p q))
(reidentifier.colour_similarity): 1 for the same distribution, 0 for disjoint ones.
"""

from __future__ import annotations

import cv2
import numpy as np

from vtrack.tracking.reidentifier import SIGNATURE_SIZE

BINS = (8, 4, 4)          # hue x saturation x value: SIGNATURE_SIZE bins
SHRINK = 0.2              # of each side left out
_RANGES = [0, 180, 0, 256, 0, 256]


def signatures(image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(D, SIGNATURE_SIZE) colour signatures of the boxes (D, 4) x, y, w, h in the BGR image; a box
    with no pixel in the image has a zero signature (similar to nothing)."""
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
    out = np.zeros((len(boxes), SIGNATURE_SIZE))
    h, w = image.shape[:2]
    x0 = np.clip(np.floor(boxes[:, 0] + SHRINK * boxes[:, 2]), 0, w).astype(int)
    y0 = np.clip(np.floor(boxes[:, 1] + SHRINK * boxes[:, 3]), 0, h).astype(int)
    x1 = np.clip(np.ceil(boxes[:, 0] + (1 - SHRINK) * boxes[:, 2]), 0, w).astype(int)
    y1 = np.clip(np.ceil(boxes[:, 1] + (1 - SHRINK) * boxes[:, 3]), 0, h).astype(int)
    for i in np.flatnonzero((x1 > x0) & (y1 > y0)):
        hsv = cv2.cvtColor(image[y0[i]:y1[i], x0[i]:x1[i]], cv2.COLOR_BGR2HSV)
        hist = cv2.calcHist([hsv], [0, 1, 2], None, list(BINS), _RANGES).ravel()
        out[i] = hist / hist.sum()
    return out
