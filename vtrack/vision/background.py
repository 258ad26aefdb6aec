"""Detector stage: MOG2 background subtraction (Zivkovic 2004, 2006) with a variance floor
and a learning-rate schedule, started from the median of frames sampled across the video's
first seconds (`median_image`)."""

from __future__ import annotations

import cv2
import numpy as np


IMAGE_EVERY = 5  # frames between recomputations of the background image


class Mog2Background:
    """MOG2 with a variance floor `var_min` (sigma >= 4 grey levels by default; OpenCV's floor
    of 4 lets H.264 texture refreshes light up foliage), learning fast during the warm-up and
    at 1 / history afterwards (see `learning_rate`)."""

    def __init__(self, history: int, var_threshold: float, var_min: float,
                 detect_shadows: bool, shadow_ratio: float, learning_rate: float,
                 warmup_frames: int) -> None:
        self.history = history
        self.fixed_rate = learning_rate
        self.warmup = warmup_frames
        self.frames = 0
        self.primed = False
        self._image: np.ndarray | None = None
        self._image_frame = 0
        self._mog = cv2.createBackgroundSubtractorMOG2(history, var_threshold, detect_shadows)
        self._mog.setShadowThreshold(shadow_ratio)
        self._mog.setVarMin(var_min)  # OpenCV keeps var_min <= var_init <= var_max
        self._mog.setVarInit(max(var_min, self._mog.getVarInit()))
        self._mog.setVarMax(max(5 * var_min, self._mog.getVarMax()))

    def learning_rate(self) -> float:
        """MOG2's fast start (-1: 1 / (2 n)) during the warm-up, then the steady 1 / history.

        A mode holding 10 % of a pixel's weight counts as background, so at the fast rate a
        vehicle covering a pixel for more than 0.2 n frames melts into the background (long
        or slow vehicles, for hundreds of frames); at 1 / 500 that takes ~50 frames.
        """
        if self.fixed_rate >= 0:
            return self.fixed_rate
        return -1.0 if self.frames <= self.warmup and not self.primed else 1.0 / self.history

    def image(self) -> np.ndarray:
        """The model's background image (its most probable colour per pixel), recomputed
        every IMAGE_EVERY frames (it changes at the learning rate, ~1/history per frame)."""
        if self._image is None or self.frames - self._image_frame >= IMAGE_EVERY:
            self._image, self._image_frame = self._mog.getBackgroundImage(), self.frames
        return self._image

    def initialise(self, background: np.ndarray) -> None:
        """Start the model from a background image: one mode per pixel at its colour, with
        MOG2's initial variance (learning rate 1)."""
        self._mog.apply(background, learningRate=1.0)
        self.primed = True

    def apply(self, small: np.ndarray) -> np.ndarray:
        """Learn `small` and return MOG2's mask (255 foreground, 127 shadow, 0 background)."""
        self.frames += 1
        return self._mog.apply(small, learningRate=self.learning_rate())


def median_image(images: list[np.ndarray]) -> np.ndarray:
    """Pixelwise median of uint8 images, rounded down: np.median(np.stack(images),
    axis=0).astype(np.uint8), by order statistics (5x faster than sorting the stack)."""
    n = len(images)
    low = _order_statistic(images, (n - 1) // 2)
    if n % 2:
        return low
    high = _order_statistic(images, n // 2)
    return ((low.astype(np.uint16) + high) // 2).astype(np.uint8)


def _order_statistic(images: list[np.ndarray], k: int) -> np.ndarray:
    """Pixelwise k-th smallest (from 0) of uint8 images: the largest value with at most k
    images below it, found bit by bit from the highest."""
    value = np.zeros_like(images[0])
    for bit in (128, 64, 32, 16, 8, 4, 2, 1):
        trial = value | np.uint8(bit)
        below = np.zeros(value.shape, np.uint16)
        for image in images:
            below += image < trial
        value = np.where(below <= k, trial, value)
    return value
