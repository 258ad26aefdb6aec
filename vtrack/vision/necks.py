"""Detector stage: blobs pinched into several bodies split at their necks (`split_necks`).

Two vehicles side by side in adjacent lanes, seen obliquely (a side or a mast view: the
near lane covers part of the far one), touch in the foreground mask at a corner and come
out as one blob. Unlike a platoon along the lane (footprint.py) the blob is not long:
its two bodies are offset on both axes. What tells them apart is that the blob pinches
between them: the distance from the blob's inside to its outline, the distance transform
D, has one peak in each body and falls low on the neck between them; a single vehicle's
filled outline (its holes filled) is one convex-ish body with one plateau of D.

With p = max D over the blob, the cores are the connected parts of {D > NECK p} whose own
maximum is at least CORE p (bodies of a similar width: a car's bonnet cut off by the
level does not count); with two cores or more, the saddle of D between any two is under
NECK p <= (NECK / CORE) times either core's peak, a neck less than ~70 % of the narrower
body's width. Each pixel of the blob goes to its nearest core (geodesic distance would be
exact; the Euclidean one is the same for bodies that touch at a neck); each part is a
detection: the bounding box of its pixels. The two largest parts must be offset on both
axes (overlapping by less than OFFSET of the smaller one's extent on each): parts side by
side along one axis are one vehicle with a notch (a window band, a shadow across a truck),
and the blob is left whole. A blob whose peak is under MIN_PEAK pixels is too thin to read
and is left alone.
"""

from __future__ import annotations

import cv2
import numpy as np

NECK = 0.5        # the level of D, as a share of the blob's peak, that separates the cores
CORE = 0.7        # a core's own peak is at least this share of the blob's
OFFSET = 0.7      # the two largest bodies overlap by less than this share on each axis
MIN_PEAK = 3.0    # detection pixels: thinner blobs are not split


def split_necks(contour: np.ndarray, min_pixels: int) -> tuple[np.ndarray, np.ndarray]:
    """One blob (its outer contour, mask pixels) split into its bodies (module docstring).
    Returns the parts' boxes (n, 4) and pixel counts (n,), parts under `min_pixels`
    dropped; no rows when the blob is one body."""
    none = np.zeros((0, 4)), np.zeros(0)
    x, y, w, h = cv2.boundingRect(contour)
    roi = np.zeros((h + 2, w + 2), np.uint8)      # a border of background around it
    cv2.drawContours(roi, [contour - np.array([x - 1, y - 1])], -1, 1, thickness=cv2.FILLED)
    dist = cv2.distanceTransform(roi, cv2.DIST_L2, 3)
    peak = float(dist.max())
    if peak < MIN_PEAK:
        return none
    n, labels = cv2.connectedComponents((dist > NECK * peak).astype(np.uint8), connectivity=8)
    if n < 3:
        return none
    tops = np.zeros(n)
    np.maximum.at(tops, labels.ravel(), dist.ravel())
    cores = np.flatnonzero(tops >= CORE * peak)
    cores = cores[cores > 0]
    if len(cores) < 2:
        return none
    seeds = np.isin(labels, cores)
    # each pixel's nearest seed pixel, by index of that pixel's component (the cores)
    _, nearest = cv2.distanceTransformWithLabels((~seeds).astype(np.uint8), cv2.DIST_L2, 3,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
    seed_core = np.zeros(int(nearest.max()) + 1, dtype=np.int32)
    seed_core[nearest[seeds]] = labels[seeds]
    owner = np.where(roi > 0, seed_core[nearest], 0)
    boxes, counts = [], []
    for core in cores:
        part = (owner == core).astype(np.uint8)
        count = int(part.sum())
        if count < min_pixels:
            continue
        px, py, pw, ph = cv2.boundingRect(part)
        boxes.append((x - 1 + px, y - 1 + py, pw, ph))
        counts.append(count)
    if len(boxes) < 2:
        return none
    boxes = np.array(boxes, dtype=float)
    a, b = boxes[np.argsort(counts)[-2:]]
    overlap = np.minimum(a[:2] + a[2:], b[:2] + b[2:]) - np.maximum(a[:2], b[:2])
    if np.any(overlap > OFFSET * np.minimum(a[2:], b[2:])):
        return none       # side by side along one axis: a notch in one body
    return boxes, np.array(counts, dtype=float)
