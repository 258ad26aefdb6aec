"""Detector stage: MOG2 background subtraction (Zivkovic 2004, 2006) with a variance floor
and a learning-rate schedule, started from a background estimated from frames sampled across
the video's first seconds (`estimate_background`): their pixelwise median, or, as an option
for dense traffic, their mode where the median is a colour the pixel seldom shows.

Where a platoon of trucks and cars (and their cast shadows) covers the road in more than half
of the samples, each time in another colour, the median is a colour of no sample: vehicles
smeared along the lane, and one blob the width of the carriageway for seconds. The road is
then still the most frequent colour -- the samples within a tolerance of it form the largest
group, vehicles scatter over many colours -- so where fewer than `support` of the samples
lie near the median, the mode is taken. A slow or waiting vehicle is a frequent colour too:
the mode bakes it into the background more crisply than the median's blend does, which is
why the option is off by default (README, Results: the suite and its regression slice)."""

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

    def apply(self, small: np.ndarray, held: np.ndarray | None = None) -> np.ndarray:
        """Learn `small` and return MOG2's mask (255 foreground, 127 shadow, 0 background).
        Inside `held` (a 0/255 mask: standing vehicles, hold.py) the model learns its own
        background image instead, and the mask there is left to the caller."""
        self.frames += 1
        if held is not None:
            small = small.copy()
            cv2.copyTo(self.image(), held, small)
        return self._mog.apply(small, learningRate=self.learning_rate())


def estimate_background(images: list[np.ndarray], tolerance: int, support: float
                        ) -> np.ndarray:
    """The background of uint8 BGR samples (HxWx3): at each pixel the median where at least
    `support` (a share) of the samples lie within `tolerance` grey levels of it in every
    channel, else the mode (`mode_image`)."""
    median = median_image(images)
    if support <= 0:
        return median
    weak = _within(images, median, tolerance) < support * len(images)
    if weak.any():   # the mode of those pixels alone, packed into a K x 1 image
        median[weak] = mode_image([image[weak][:, None] for image in images],
                                  tolerance)[:, 0]
    return median


def mode_image(images: list[np.ndarray], tolerance: int) -> np.ndarray:
    """Pixelwise mode of uint8 BGR samples (HxWx3): of the samples, the one with the most
    others within `tolerance` grey levels in every channel (Chebyshev distance; the first of
    equals), and the mean of that group, rounded."""
    n = len(images)
    low, high = zip(*(_bounds(image, tolerance) for image in images))
    group = np.ones((n,) + images[0].shape[:2], np.uint16)   # each sample is near itself
    for j in range(n):
        for i in range(j + 1, n):       # the distance is symmetric: each pair once
            near = cv2.inRange(images[i], low[j], high[j]) >> 7   # 0 / 1
            group[j] += near
            group[i] += near
    best = group.argmax(axis=0)
    centre = np.take_along_axis(np.stack(images), best[None, ..., None], axis=0)[0]
    total = np.zeros(centre.shape, np.float32)
    count = np.zeros(centre.shape[:2], np.float32)
    lo, hi = _bounds(centre, tolerance)
    for image in images:
        near = cv2.inRange(image, lo, hi)
        cv2.accumulate(image, total, near)
        cv2.accumulate(near, count)
    return np.rint(total / (count[..., None] / 255.0)).astype(np.uint8)  # count: 255 per sample


def _within(images: list[np.ndarray], colour: np.ndarray, tolerance: int) -> np.ndarray:
    """(H, W) how many of the samples lie within `tolerance` of `colour` in every channel."""
    lo, hi = _bounds(colour, tolerance)
    count = np.zeros(colour.shape[:2], np.uint16)
    for image in images:
        count += cv2.inRange(image, lo, hi) >> 7
    return count


def _bounds(image: np.ndarray, tolerance: int) -> tuple[np.ndarray, np.ndarray]:
    """image -/+ tolerance in every channel, saturated (cv2.inRange's bounds)."""
    t = (tolerance,) * 3 + (0,)
    return cv2.subtract(image, t), cv2.add(image, t)


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
