"""Detector stage: cast shadows out of the foreground, dark vehicles kept.

MOG2 (with shadow detection) labels a pixel shadow (127) when it is a darker copy of the
background: brightness ratio between tau (`shadow_ratio`) and 1 at about the background's
chromaticity (Prati et al. 2003, the "deterministic non-model" test). A dark grey vehicle
on grey asphalt passes that test too. What tells them apart is texture: a shadow darkens
the road it falls on by one factor, so the ratio frame / background is smooth across it and
the road's own texture shows through, while a vehicle brings outlines, windows and lights of
its own (Sanin et al. 2012 review texture tests for this reason). Per shadow-labelled pixel
the standard deviation of the ratio over the shadow-labelled pixels of a `window` x `window`
box (so that a vehicle's edge next to its shadow does not count as texture) is compared
with `texture`: below it the pixel is shadow and dropped, above it the pixel is kept as
foreground.
"""

from __future__ import annotations

import cv2
import numpy as np

SHADOW = 127  # MOG2's shadow label


def drop_shadows(raw: np.ndarray, threshold: int) -> np.ndarray:
    """Binary mask (0/255) of the mask values >= threshold: MOG2 labels shadow pixels 127,
    so the default threshold 200 drops them all."""
    return cv2.threshold(raw, threshold - 1, 255, cv2.THRESH_BINARY)[1]


def textured_shadow(raw: np.ndarray, frame: np.ndarray, background: np.ndarray,
                    texture: float, window: int = 5) -> np.ndarray:
    """Binary mask (0/255): MOG2's foreground plus the shadow-labelled pixels whose
    frame / background ratio is not smooth (std over the window above `texture`): parts of
    vehicles MOG2 took for shadow."""
    fg = np.where(raw == 255, np.uint8(255), np.uint8(0))
    candidates = raw == SHADOW
    if not candidates.any():
        return fg
    f = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY).astype(np.float32)
    b = cv2.cvtColor(background, cv2.COLOR_BGR2GRAY).astype(np.float32)
    w = candidates.astype(np.float32)
    ratio = f / (b + 1.0) * w
    k = (window, window)
    n = np.maximum(cv2.blur(w, k), 1e-6)   # statistics over the window's shadow pixels only
    mean = cv2.blur(ratio, k) / n
    var = cv2.blur(ratio * ratio, k) / n - mean * mean
    # The ring of blurred pixels around a vehicle's outline looks like textured shadow:
    # pixels next to the foreground are not judged (the closing fills a vehicle's holes).
    ring = cv2.dilate(fg, np.ones((3, 3), np.uint8)) > 0
    vehicle = candidates & ~ring & (var > texture * texture)
    fg[vehicle] = 255
    return fg
