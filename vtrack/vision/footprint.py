"""Detector stage: blobs longer than a vehicle split at their waists (`split_footprint`).

Vehicles one behind the other along a lane (a platoon seen from behind, the near lane
covering the far one in a side view) touch in the foreground mask and come out as one long
blob. When the tracker has no separate predicted boxes for them (split.py needs two), the
blob's own shape still tells them apart: seen along its long axis, the blob narrows where
one vehicle ends and the next begins (the road or a thin cast shadow between them), while
a single vehicle, however long, keeps its width.

The expected size of a vehicle at the blob's place is the scale field s(x, y) (sizes.py: the
side sqrt(w h) of the tracked vehicles' boxes there). A blob whose long side L exceeds
`LONG` s is cut along its long axis where its cross-section (the blob's pixels in one
column, or row) is at its minimum over the part that leaves both sides at least
`MIN_PIECE` s long, when that minimum is under `WAIST` times the median cross-section of
the part: one vehicle's width falls that far only between vehicles. Each side is cut again
the same way; each piece, less the waist at its ends (cross-section under `WAIST` times
the blob's median), is a detection: the bounding box of its pixels.
"""

from __future__ import annotations

import cv2
import numpy as np

LONG = 2.0        # a blob longer than this many expected vehicle sides may hold several
MIN_PIECE = 0.7   # no piece shorter than this many expected sides
WAIST = 0.5       # a cut where the cross-section falls under this share of the median


def cuts(profile: np.ndarray, min_piece: float) -> list[int]:
    """Where to cut a blob whose cross-section along its long axis is `profile` (L,)
    (pixels per column): the minimum over [min_piece, L - min_piece) when it is under
    WAIST times the profile's median, then the same on each side; sorted."""
    n = len(profile)
    lo, hi = int(np.ceil(min_piece)), int(n - np.ceil(min_piece))
    if hi <= lo:
        return []
    i = lo + int(np.argmin(profile[lo:hi]))
    if profile[i] >= WAIST * np.median(profile):
        return []
    return ([*cuts(profile[:i], min_piece), i]
            + [i + j for j in cuts(profile[i:], min_piece)])


def split_long(contour: np.ndarray, side: float, min_pixels: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """One blob (its outer contour, mask pixels) cut at its waists when it is longer than
    LONG expected vehicle sides `side` (module docstring). Returns the pieces' boxes (n, 4)
    and pixel counts (n,), pieces under `min_pixels` dropped; no rows when it is not cut."""
    x, y, w, h = cv2.boundingRect(contour)
    if side <= 0 or max(w, h) <= LONG * side:
        return np.zeros((0, 4)), np.zeros(0)
    roi = np.zeros((h, w), np.uint8)
    cv2.drawContours(roi, [contour - np.array([x, y])], -1, 1, thickness=cv2.FILLED)
    axis = 0 if w >= h else 1            # the profile runs along the long side
    profile = roi.sum(axis=axis).astype(float)
    profile = np.convolve(profile, np.ones(3) / 3, mode="same")   # one-pixel notches
    at = cuts(profile, MIN_PIECE * side)
    if not at:
        return np.zeros((0, 4)), np.zeros(0)
    boxes, counts = [], []
    low = WAIST * np.median(profile)
    for a, b in zip([0, *at], [*at, len(profile)], strict=True):
        while a < b and profile[a] < low:       # the waist belongs to neither vehicle
            a += 1
        while b > a and profile[b - 1] < low:
            b -= 1
        part = roi[:, a:b] if axis == 0 else roi[a:b]
        n = int(part.sum())
        if n < min_pixels:
            continue
        px, py, pw, ph = cv2.boundingRect(np.ascontiguousarray(part))
        ox, oy = (x + a, y) if axis == 0 else (x, y + a)
        boxes.append((ox + px, oy + py, pw, ph))
        counts.append(n)
    if len(boxes) < 2:
        return np.zeros((0, 4)), np.zeros(0)
    return np.array(boxes, dtype=float), np.array(counts, dtype=float)
