"""Detector stage: the noise floor in vehicle units.

A camera on a mast sees a car at the far end as a 10 px square (100 px^2) and near the
camera as 60 px; a floor of 150 px^2 drops every far car, a floor of 40 px^2 lets through
the speckle of foliage and codec noise near the camera. The floor a blob must pass is
therefore a share of the area a vehicle has at its place, never below an absolute floor
for the noise and never above `min_pixels`:

    floor(x, y) = clip(share * s(x, y)^2, min_far, min_pixels),
    s(x, y) = a + b x / W + c y / H,

with s the side sqrt(w h) of a vehicle's box: on a road plane seen through a pinhole camera
the image size of a vehicle is close to linear in its image position (it falls to zero at
the horizon; tracking/scale_field.py). (a, b, c) are fitted by least squares, with Cauchy
weights on the relative residual (merged boxes and parts weigh little) and a small ridge
toward the flat field b = c = 0,
to the boxes the tracker predicts for its confirmed vehicles over the last `MEMORY` of them
(mask pixels). Until `MIN_BOXES` have been seen, the floor is `min_pixels` everywhere.
The boxes the tracker has are biased toward large vehicles where vehicles are small (a far
vehicle is tracked mostly when merged with its neighbour), which `share` absorbs.
"""

from __future__ import annotations

from collections import deque

import numpy as np

MEMORY = 3000       # predicted boxes kept for the fit
MIN_BOXES = 200     # boxes before the fit is used
REFIT_EVERY = 25    # frames between fits
RIDGE = 1e-4        # pull of b, c toward the flat field (u, v vary by ~0.25)
CAUCHY = 0.3        # relative residual scale of the Cauchy weights


class SizeFloor:
    """The per-place noise floor (mask pixels^2) learnt from predicted boxes."""

    def __init__(self, width: int, height: int, share: float, min_far: int,
                 min_pixels: int, coef: np.ndarray | None = None,
                 side_share: float = 0.0) -> None:
        """`coef`: a fixed field (a, b, c), nothing learnt (the far band's, far.py);
        `side_share`: of the expected side, a blob's shortest width and height."""
        self.size = np.array([width, height], dtype=float)
        self.share, self.min_far, self.min_pixels = share, min_far, min_pixels
        self.side_share = side_share
        self._samples: deque[np.ndarray] = deque(maxlen=MEMORY)   # x/W, y/H, s
        self._frames = 0
        self.coef: np.ndarray | None = coef   # a, b, c
        self.fixed = coef is not None

    def add(self, boxes: np.ndarray) -> None:
        """Learn from one frame's predicted boxes (K, 4) x, y, w, h in mask pixels."""
        if self.fixed:
            return
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        ok = (boxes[:, 2] > 1) & (boxes[:, 3] > 1)
        if ok.any():
            centre = (boxes[ok, :2] + boxes[ok, 2:] / 2) / self.size
            side = np.sqrt(boxes[ok, 2] * boxes[ok, 3])
            self._samples.extend(np.column_stack([centre, side]))
        self._frames += 1
        if len(self._samples) >= MIN_BOXES and self._frames % REFIT_EVERY == 0:
            self.coef = fit_size(np.array(self._samples))

    def side(self, centres: np.ndarray) -> np.ndarray | None:
        """The expected side s(x, y) (N,) of a vehicle's box at centres (N, 2), mask pixels;
        None before the first fit."""
        if self.coef is None:
            return None
        return np.maximum(self.coef[0] + (centres / self.size) @ self.coef[1:], 0.0)

    def least_side(self, centres: np.ndarray) -> np.ndarray:
        """The shortest width and height (N,) of a blob at centres (N, 2): `side_share`
        of a vehicle's expected side there (0 before the first fit), mask pixels."""
        side = self.side(centres)
        return np.zeros(len(centres)) if side is None else self.side_share * side

    def __call__(self, centres: np.ndarray) -> np.ndarray:
        """The floor (N,) at blob centres (N, 2), mask pixels."""
        side = self.side(centres)
        if side is None:
            return np.full(len(centres), float(self.min_pixels))
        return np.clip(self.share * side ** 2, self.min_far, self.min_pixels)


def fit_size(samples: np.ndarray, iterations: int = 5) -> np.ndarray:
    """(a, b, c) of s = a + b u + c v over samples (N, 3) u, v, s: iteratively reweighted
    least squares with Cauchy weights 1 / (1 + (r / (CAUCHY s_hat))^2) and a ridge RIDGE
    (times N) on b and c (normal equations (A^T W A + R) x = A^T W y)."""
    a = np.column_stack([np.ones(len(samples)), samples[:, :2]])
    y = samples[:, 2]
    ridge = np.diag([0.0, RIDGE, RIDGE]) * len(samples)
    w = np.ones(len(samples))
    coef = np.zeros(3)
    for _ in range(iterations):
        aw = a * w[:, None]
        coef = np.linalg.solve(aw.T @ a + ridge, aw.T @ y)
        r = (y - a @ coef) / np.maximum(a @ coef, 1.0)
        w = 1.0 / (1.0 + (r / CAUCHY) ** 2)
    return coef
