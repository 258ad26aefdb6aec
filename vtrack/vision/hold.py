"""Detector stage: standing vehicles kept out of the background (selective update).

MOG2 learns every pixel at 1 / history: a vehicle that stops in a queue becomes background
within ~2 s (a mode holding 10 % of a pixel's weight is background), its blob fades, and
when it drives off the model shows a ghost where it stood. The tracker knows where its
confirmed vehicles are; those whose predicted box stands still are held:

- `StandingBoxes` follows the predicted boxes (mask pixels, no identities) from frame to
  frame: a box whose centre moved less than `speed` box scales per second since the nearest
  box of the previous frame (and whose size changed by under that much) has stood one frame
  longer; boxes that have stood `min_frames` and at most `max_frames` are held.
- `held_foreground` is MOG2 without learning there: the model learns its own background
  image inside the held boxes (so it keeps the road and forgets nothing else), and the
  foreground inside them is the frame against that image by MOG2's own tests (Zivkovic's
  squared distance over var_threshold * var_min; a darker copy of the background at the
  background's chromaticity with brightness ratio in [tau, 1] is labelled shadow, 127,
  Prati et al. 2003), so the later stages see the same labels.

A vehicle held while it stands never enters the model, so it leaves no ghost when it
drives off. The motion check (blobs.find_blobs) lets a blob through that holds a held box's
centre: a standing vehicle does not change between frames.
"""

from __future__ import annotations

import cv2
import numpy as np

SHADOW = 127


class StandingBoxes:
    """Which predicted boxes (mask pixels) have stood still for long enough to be held."""

    def __init__(self, speed: float, fps: float, min_frames: int, max_frames: int) -> None:
        self.step = speed / max(fps, 1e-6)   # box scales per frame
        self.min_frames, self.max_frames = min_frames, max_frames
        self._boxes = np.zeros((0, 4))
        self._stood = np.zeros(0, dtype=np.int64)

    def __call__(self, boxes: np.ndarray) -> np.ndarray:
        """The boxes (K, 4) x, y, w, h of this frame to hold: each inherits the standing
        time of the previous frame's box nearest its centre when it moved less than `speed`
        box scales per second since (centre and size), else starts again."""
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        stood = np.zeros(len(boxes), dtype=np.int64)
        if len(boxes) and len(self._boxes):
            c = boxes[:, :2] + boxes[:, 2:] / 2
            p = self._boxes[:, :2] + self._boxes[:, 2:] / 2
            dist = np.linalg.norm(c[:, None] - p[None], axis=2)
            j = dist.argmin(axis=1)
            scale = np.sqrt(np.maximum(boxes[:, 2] * boxes[:, 3], 1.0))
            grow = np.abs(np.sqrt(np.maximum(self._boxes[j, 2] * self._boxes[j, 3], 1.0))
                          - scale)
            still = (dist[np.arange(len(boxes)), j] < self.step * scale) & \
                    (grow < self.step * scale)
            stood = np.where(still, self._stood[j] + 1, 0)
        self._boxes, self._stood = boxes, stood
        held = (stood >= self.min_frames) & (stood <= self.max_frames)
        return boxes[held]


def hold_mask(boxes: np.ndarray, shape: tuple[int, int]) -> np.ndarray | None:
    """A 0/255 mask of `shape` (h, w) with the boxes (x, y, w, h, mask pixels) filled; None
    without boxes inside the image."""
    if len(boxes) == 0:
        return None
    mask = np.zeros(shape, np.uint8)
    for x, y, w, h in np.rint(boxes).astype(np.int64):
        cv2.rectangle(mask, (int(x), int(y)), (int(x + w) - 1, int(y + h) - 1), 255, -1)
    return mask if mask.any() else None


def held_foreground(small: np.ndarray, background: np.ndarray, held: np.ndarray,
                    var_threshold: float, var_min: float, shadow_ratio: float,
                    shadows: bool) -> np.ndarray:
    """MOG2's labels (0 / 127 / 255) of the frame `small` inside the `held` mask against the
    background image, with the variance at its floor: foreground where |x - mu|^2 >
    var_threshold var_min; shadow where, for a = x.mu / mu.mu in [tau, 1],
    |x - a mu|^2 < var_threshold var_min a^2 (cv2 BackgroundSubtractorMOG2's detectShadowGMM).
    Zero outside the mask."""
    out = np.zeros(held.shape, np.uint8)
    x, y, w, h = cv2.boundingRect(held)
    sub = (slice(y, y + h), slice(x, x + w))
    f = small[sub].astype(np.float32)
    mu = background[sub].astype(np.float32)
    limit = var_threshold * var_min
    fg = np.sum((f - mu) ** 2, axis=2) > limit
    labels = np.where(fg, 255, 0).astype(np.uint8)
    if shadows:
        a = np.sum(f * mu, axis=2) / np.maximum(np.sum(mu * mu, axis=2), 1e-6)
        off = np.sum((f - a[..., None] * mu) ** 2, axis=2)
        shade = fg & (a >= shadow_ratio) & (a <= 1.0) & (off < limit * a * a)
        labels[shade] = SHADOW
    out[sub] = labels
    return cv2.bitwise_and(out, held)
