"""Detector stage: foreground that a small shift of the background explains.

A swaying camera warped back onto its reference (stabilise.py) is registered to about a
pixel, not exactly, and not everywhere: a similarity transform cannot follow a kerb or a
guard rail standing above the road (parallax), and resampling blurs. At a sharp edge of the
background -- a kerb, a lane marking, the line where asphalt meets grass -- a shift of half
a pixel changes the grey level by half the edge's contrast, and MOG2, a per-pixel model,
calls that foreground: thin lines the width of the picture, which the closing then joins to
the vehicles on them (a truck's blob spanning the frame).

Background subtraction with a spatial neighbourhood (ViBe and PBAS compare a pixel with the
models of its neighbours, Barnich & Van Droogenbroeck 2011) takes such a pixel for
background when it matches the background somewhere near it. Here a foreground pixel is
background when its colour lies, in every channel, within `tolerance` grey levels of the
colours between two adjacent background pixels within `radius` of it: what the background
looks like shifted by up to `radius` px, sub-pixel shifts included (they mix two adjacent
pixels). Over smooth road those colours are the road's, and with a tolerance of half of
MOG2's threshold at its variance floor (4 sigma, sigma >= 4: 16 grey levels) a vehicle's
pixel stays; at an edge a vehicle's pixel must differ from every blend of two neighbours
there. (The range of the whole window instead, one box per channel, is far looser where
grass, asphalt and white paint meet: it ate the pieces of a van on the side-view preset.)
The stage runs only once the camera has moved (the stabiliser's `moved`): a still camera
has no registration to get wrong.
"""

from __future__ import annotations

import cv2
import numpy as np


FIRST_RADIUS = 2   # a larger radius tests first the window of this one (`_blends`)


class ShiftTolerance:
    """Per frame: the foreground mask (0/255) without the pixels that a shift of the
    background by up to `radius` px explains."""

    def __init__(self, tolerance: float, radius: int) -> None:
        self.tolerance = int(round(tolerance))
        self.radius = radius
        self.kernel = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
        self._background: np.ndarray | None = None
        self._range: tuple[np.ndarray, np.ndarray] | None = None

    def bounds(self, background: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(low, high): the background's per-channel minimum and maximum over the window,
        widened by the tolerance (saturating); recomputed only when the background image
        changes (Mog2Background.image refreshes it every few frames)."""
        if background is not self._background or self._range is None:
            t = (self.tolerance,) * 3 + (0,)
            self._range = (cv2.subtract(cv2.erode(background, self.kernel), t),
                           cv2.add(cv2.dilate(background, self.kernel), t))
            self._background = background
        return self._range

    def __call__(self, fg: np.ndarray, frame: np.ndarray, background: np.ndarray
                 ) -> np.ndarray:
        """fg (HxW, 0/255) without the pixels of `frame` (HxWx3) that a shift of
        `background` (HxWx3) explains. The window's range (`bounds`) is a necessary
        condition and cheap: only the foreground pixels inside it get the blend test."""
        low, high = self.bounds(background)
        candidates = cv2.bitwise_and(cv2.inRange(frame, low, high), fg)
        if cv2.countNonZero(candidates) == 0:
            return fg
        xs, ys = cv2.findNonZero(candidates).reshape(-1, 2).T
        out = fg.copy()
        for radius in sorted({min(self.radius, FIRST_RADIUS), self.radius}):
            explained = self._blends(frame[ys, xs], background, ys, xs, radius)
            out[ys[explained], xs[explained]] = 0
            ys, xs = ys[~explained], xs[~explained]
        return out

    def _blends(self, colours: np.ndarray, background: np.ndarray, ys: np.ndarray,
                xs: np.ndarray, radius: int) -> np.ndarray:
        """(K,) whether each colour c (K, 3) lies within the tolerance t of the per-channel
        interval between two 4-adjacent background pixels a, b of the window around
        (ys, xs) (image edges replicated): min(a, b) - t <= c <= max(a, b) + t in every
        channel, i.e. in no channel are both a < c - t or both b > c + t. Each window
        pixel's six such flags (below / above, per channel) are packed into one byte, so a
        pair misses the colour where the AND of its bytes is non-zero. The window of a
        smaller radius holds a subset of the pairs, so `__call__` tests the pixels it does
        not explain, alone, with the full radius: the same result, at a fraction of the
        cost where most are explained near by."""
        h, w = background.shape[:2]
        d = np.arange(-radius, radius + 1)
        rows = np.clip(ys[:, None] + d, 0, h - 1)
        cols = np.clip(xs[:, None] + d, 0, w - 1)
        win = background[rows[:, :, None], cols[:, None, :]]          # K,n,n,3 uint8
        c = colours.astype(np.int16)
        # saturated bounds: where c - t < 0 no pixel lies below it, nor above c + t > 255
        low = np.clip(c - self.tolerance, 0, 255).astype(np.uint8)[:, None, None, :]
        high = np.clip(c + self.tolerance, 0, 255).astype(np.uint8)[:, None, None, :]
        below = (win < low).view(np.uint8)
        above = (win > high).view(np.uint8)
        flags = (below[..., 0] | below[..., 1] << 1 | below[..., 2] << 2
                 | above[..., 0] << 3 | above[..., 1] << 4 | above[..., 2] << 5)
        found = ((flags[:, :, :-1] & flags[:, :, 1:]) == 0).any(axis=(1, 2))
        found |= ((flags[:, :-1, :] & flags[:, 1:, :]) == 0).any(axis=(1, 2))
        return found
