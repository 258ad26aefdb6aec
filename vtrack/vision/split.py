"""Detector stage: blobs that hold several tracked vehicles split among them.

Vehicles side by side, or one just behind another along the line of sight, touch in the
foreground mask and come out as one blob, whose centre and box belong to none of them. When
a blob holds the predicted boxes of two or more tracked vehicles (each predicted box mostly
on the blob, the boxes not one on top of the other), its pixels are divided among them:
each pixel goes to the box it is nearest to in that box's own units,

    d_k(p) = max(|p_x - c_kx| / (w_k / 2), |p_y - c_ky| / (h_k / 2)),

(d <= 1 inside box k), pixels further than `reach` from every box are dropped, and each
vehicle's detection is the bounding box of its pixels.
"""

from __future__ import annotations

import cv2
import numpy as np

from vtrack.boxes import centre, intersection, overlap_of_smaller

REACH = 1.5        # pixels beyond 1.5 half-sizes of every predicted box belong to none
MIN_COVER = 0.5    # share of a predicted box that must lie on the blob's bounding box
MAX_OVERLAP = 0.5  # two predicted boxes overlapping more than this are one vehicle


def holders(blob: np.ndarray, priors: np.ndarray) -> np.ndarray:
    """Indices of the predicted boxes `priors` (P, 4) that a blob box (4,) holds: centre on
    the blob's box, most of the predicted box on it; of two predicted boxes that overlap
    each other mostly, only the first."""
    if len(priors) < 2:
        return np.zeros(0, dtype=int)
    c = centre(priors)
    inside = np.all((c >= blob[:2]) & (c <= blob[:2] + blob[2:]), axis=1)
    cover = intersection(priors, blob[None]) / np.maximum(priors[:, 2] * priors[:, 3], 1e-9)
    idx = np.flatnonzero(inside & (cover >= MIN_COVER))
    keep: list[int] = []
    for i in idx:
        if not keep or not np.any(overlap_of_smaller(priors[i], priors[keep]) > MAX_OVERLAP):
            keep.append(int(i))
    return np.array(keep if len(keep) >= 2 else [], dtype=int)


def split_blob(contour: np.ndarray, priors: np.ndarray, min_pixels: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Divide the pixels of one blob (its outer contour, mask pixels) among the predicted
    boxes `priors` (K, 4, mask pixels). Returns the pieces' boxes (n, 4) and pixel counts
    (n,); pieces under min_pixels are dropped."""
    x, y, w, h = cv2.boundingRect(contour)
    roi = np.zeros((h, w), np.uint8)
    cv2.drawContours(roi, [contour - np.array([x, y])], -1, 1, thickness=cv2.FILLED)
    v, u = np.nonzero(roi)
    pu, pv = u + x + 0.5, v + y + 0.5
    c = centre(priors)
    half = np.maximum(priors[:, 2:] / 2, 0.5)
    d = np.maximum(np.abs(pu[None] - c[:, None, 0]) / half[:, None, 0],
                   np.abs(pv[None] - c[:, None, 1]) / half[:, None, 1])
    owner = np.argmin(d, axis=0)
    owner[d.min(axis=0) > REACH] = -1
    boxes, areas = [], []
    for k in range(len(priors)):
        mine = owner == k
        n = int(mine.sum())
        if n < min_pixels:
            continue
        u0, u1 = u[mine].min() + x, u[mine].max() + x + 1
        v0, v1 = v[mine].min() + y, v[mine].max() + y + 1
        boxes.append((u0, v0, u1 - u0, v1 - v0))
        areas.append(n)
    return np.array(boxes, dtype=float).reshape(-1, 4), np.array(areas, dtype=float)
