"""Detector stage: camera motion compensation.

A camera on a pole or a bridge sways and vibrates: a shift of one or two pixels lights up
every lane marking and kerb in the background model. The stage estimates, per frame, the
similarity transform M (rotation, scale, translation) that maps a fixed reference frame onto
the current one -- Lucas-Kanade optical flow of corner features of the reference, RANSAC fit
(estimateAffinePartial2D) -- and warps the frame back onto the reference, so the background
model sees a still scene. Against a fixed reference (not frame to frame) the estimate does not
drift. If the reference is lost (too few inliers: the view changed too much), the current
frame becomes the reference, placed where the last estimate put the previous frame, so the
output coordinates stay the same (`reanchored` counts these).

Static cameras pay nothing after the probe: if M stays within `still_px` of the identity at
the image corners over the first `probe_frames` frames, the stage switches itself off.
"""

from __future__ import annotations

import cv2
import numpy as np

IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
STILL_WARP_PX = 0.25  # a transform moving no image corner further than this is no motion


def corner_shift(M: np.ndarray, width: int, height: int) -> float:
    """Largest displacement (px) of the image corners under the 2x3 transform M."""
    c = np.array([[0, 0], [width, 0], [0, height], [width, height]], dtype=float)
    return float(np.abs(c @ M[:, :2].T + M[:, 2] - c).max())


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The 2x3 transform of applying b, then a."""
    return np.hstack([a[:, :2] @ b[:, :2], (a[:, :2] @ b[:, 2] + a[:, 2])[:, None]])


def invert(m: np.ndarray) -> np.ndarray:
    """The inverse of a 2x3 affine transform."""
    return cv2.invertAffineTransform(m)


def rescale(m: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """M in pixels scaled by (sx, sy): S M S^-1 with S = diag(sx, sy)."""
    S = np.array([sx, sy])
    return np.hstack([m[:, :2] * S[:, None] / S[None, :], (m[:, 2] * S)[:, None]])


def transform_boxes(m: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Axis-aligned boxes (x, y, w, h) mapped by M: the bounding boxes of their corners."""
    if len(boxes) == 0 or np.array_equal(m, IDENTITY):
        return boxes
    x0, y0 = boxes[:, 0], boxes[:, 1]
    x1, y1 = x0 + boxes[:, 2], y0 + boxes[:, 3]
    cx = np.stack([x0, x1, x0, x1], axis=1)
    cy = np.stack([y0, y0, y1, y1], axis=1)
    u = m[0, 0] * cx + m[0, 1] * cy + m[0, 2]
    v = m[1, 0] * cx + m[1, 1] * cy + m[1, 2]
    lo = np.stack([u.min(axis=1), v.min(axis=1)], axis=1)
    hi = np.stack([u.max(axis=1), v.max(axis=1)], axis=1)
    return np.hstack([lo, hi - lo])


class Stabiliser:
    """Per frame: (the frame warped onto the reference, M reference -> current frame)."""

    def __init__(self, width: int, height: int, probe_frames: int, still_px: float,
                 est_width: int = 320) -> None:
        self.width, self.height = width, height
        self.s = max(1.0, width / est_width)          # estimation at <= est_width pixels
        self.est_size = (max(1, round(width / self.s)), max(1, round(height / self.s)))
        self.probe_frames, self.still_px = probe_frames, still_px
        self.active = True
        self.frames = 0
        self.max_shift = 0.0
        self.reanchored = 0
        self.M = IDENTITY.copy()
        self._base = IDENTITY.copy()   # the first reference -> the current reference
        self._ref: np.ndarray | None = None
        self._pts: np.ndarray | None = None

    @property
    def moved(self) -> bool:
        """Whether the camera has moved by more than `still_px` so far."""
        return self.max_shift > self.still_px

    def _grey(self, small: np.ndarray) -> np.ndarray:
        g = cv2.cvtColor(small, cv2.COLOR_BGR2GRAY)
        return g if self.s == 1 else cv2.resize(g, self.est_size, interpolation=cv2.INTER_AREA)

    def set_reference(self, small: np.ndarray) -> None:
        """Make `small` (a frame at the detection resolution) the reference."""
        self._ref = self._grey(small)
        pts = cv2.goodFeaturesToTrack(self._ref, 200, 0.01, 10, blockSize=7)
        self._pts = pts if pts is not None else np.zeros((0, 1, 2), np.float32)

    def estimate(self, small: np.ndarray) -> np.ndarray | None:
        """M (2x3, detection pixels) mapping the reference onto `small`, or None when the
        reference is lost."""
        if self._ref is None:
            self.set_reference(small)
            return IDENTITY.copy()
        if len(self._pts) < 12:
            return None
        grey = self._grey(small)
        nxt, status, _ = cv2.calcOpticalFlowPyrLK(self._ref, grey, self._pts, None,
                                                  winSize=(15, 15), maxLevel=3)
        ok = status.ravel() == 1
        if ok.sum() < 12:
            return None
        m, inliers = cv2.estimateAffinePartial2D(self._pts[ok], nxt[ok], method=cv2.RANSAC,
                                                 ransacReprojThreshold=1.0)
        if m is None or inliers.sum() < max(12, 0.25 * len(self._pts)):
            return None
        s = self.s
        m[:, 2] *= s  # estimation pixels -> detection pixels (the linear part is unchanged)
        return m

    def align(self, small: np.ndarray) -> np.ndarray:
        """`small` warped onto the reference (the first frame aligned becomes it), without
        counting it as a frame of the video."""
        m = self.estimate(small)
        return small if m is None else _warp(small, m)

    def __call__(self, small: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(small warped onto the reference, M reference -> current) for the next frame."""
        self.frames += 1
        if not self.active:
            return small, IDENTITY
        m = self.estimate(small)
        if m is None:
            # Lost (the view changed too much for the reference's features): this frame
            # becomes the reference, placed where the last estimate put the previous one,
            # so the output coordinates -- and the background model -- stay the same.
            self._base = self.M
            self.set_reference(small)
            self.reanchored += 1
            m = IDENTITY.copy()
        m = compose(m, self._base)
        self.M = m
        self.max_shift = max(self.max_shift, corner_shift(m, self.width, self.height))
        if self.frames >= self.probe_frames and self.max_shift <= self.still_px:
            self.active = False  # a still camera: nothing to compensate
        if corner_shift(m, self.width, self.height) <= STILL_WARP_PX:
            return small, IDENTITY   # below what resampling could represent: no motion
        return _warp(small, m), m


def _warp(small: np.ndarray, m: np.ndarray) -> np.ndarray:
    """`small` resampled onto the reference by M (reference -> small); unchanged when M
    moves no corner by more than a quarter pixel (resampling blurs more than that moves)."""
    h, w = small.shape[:2]
    if corner_shift(m, w, h) <= STILL_WARP_PX:
        return small
    return cv2.warpAffine(small, m, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE)
