"""Detector stage: cast shadows out of the foreground, dark vehicles kept.

MOG2 (with shadow detection) labels a pixel shadow (127) when it is a darker copy of the
background: brightness ratio between tau (`shadow_ratio`) and 1 at about the background's
chromaticity (Prati et al. 2003, the "deterministic non-model" test). A dark grey vehicle
on grey asphalt passes that test too. What tells them apart is texture: a shadow darkens
the road it falls on by one factor r, so the road's own texture shows through, dimmed --
the frame's local standard deviation is r times the background's -- while a vehicle brings
its own: smooth paint over grainy asphalt loses the road's texture, outlines, windows and
lights add texture where the road had none (Sanin et al. 2012 review texture tests). Pixels
that fail the test are kept as foreground, the others dropped as shadow (`texture`,
relative; `NOISE_GREY` absolute). A vehicle whose paint matches the road shows only its
outline, and an outline is a thin line that the per-window test cannot judge: long thin
dark lines the background does not have are kept as well (`LINE_GREY`, `LINE_PX`).
"""

from __future__ import annotations

import cv2
import numpy as np

SHADOW = 127      # MOG2's shadow label
NOISE_GREY = 3.0  # differences of local standard deviation under this are sensor noise
LINE_GREY = 10.0  # a thin dark line this much deeper than the background's is a vehicle's,
LINE_PX = 12      # if at least this long (a far vehicle's shadow is a short dark strip)


def drop_shadows(raw: np.ndarray, threshold: int) -> np.ndarray:
    """Binary mask (0/255) of the mask values >= threshold: MOG2 labels shadow pixels 127,
    so the default threshold 200 drops them all."""
    return cv2.threshold(raw, threshold - 1, 255, cv2.THRESH_BINARY)[1]


def textured_shadow(raw: np.ndarray, frame: np.ndarray, background: np.ndarray,
                    texture: float, window: int = 5) -> np.ndarray:
    """Binary mask (0/255): MOG2's foreground plus the shadow-labelled pixels whose local
    texture is not the background's dimmed by the shadow: |s_f - r s_b| above
    max(texture * r s_b, NOISE_GREY), with s_f, s_b the standard deviations of frame and
    background over the window and r their mean ratio (a shadow keeps s_f = r s_b; smooth
    paint over a grainy road loses it, a textured vehicle over a smooth road adds its own),
    and those on long thin dark lines that the background lacks (a vehicle's outline)."""
    fg = cv2.threshold(raw, 254, 255, cv2.THRESH_BINARY)[1]  # MOG2's foreground (255)
    candidates = cv2.compare(raw, SHADOW, cv2.CMP_EQ)
    x, y, w, h = cv2.boundingRect(candidates)
    if w == 0:
        return fg
    k = (window, window)
    # Only the region around the shadow-labelled pixels is examined, and the tests are
    # evaluated at those pixels alone (`at`: their flat indices in the region).
    m = window
    x0, y0 = max(x - m, 0), max(y - m, 0)
    x1, y1 = min(x + w + m, raw.shape[1]), min(y + h + m, raw.shape[0])
    sub = (slice(y0, y1), slice(x0, x1))
    candidates = candidates[sub]
    at = np.flatnonzero(candidates > 0)
    f = cv2.cvtColor(frame[sub], cv2.COLOR_BGR2GRAY)
    b = cv2.cvtColor(background[sub], cv2.COLOR_BGR2GRAY)
    mf, sf = _mean_std(f, k, at)
    mb, sb = _mean_std(b, k, at)
    ratio = mf / (mb + 1.0)
    expected = ratio * sb
    differs = np.abs(sf - expected) > np.maximum(texture * expected, NOISE_GREY)
    # Blurred edges -- the ring around a vehicle's outline, the rim of a shadow -- mix two
    # brightness levels and look textured: only pixels with shadow-labelled neighbours all
    # round are judged (the closing fills a vehicle's holes again).
    inner = cv2.erode(candidates, np.ones(k, np.uint8)).take(at) > 0
    # Thin dark lines -- a vehicle's outline, window frames, the gap under a bumper -- one or
    # two pixels wide; a shadow has none of its own, only the road's dimmed: the 3x3
    # black-hat (closing minus image) of the frame above r times the background's.
    thin = np.ones((3, 3), np.uint8)
    dark = (cv2.morphologyEx(f, cv2.MORPH_BLACKHAT, thin).take(at).astype(np.float32)
            - ratio * cv2.morphologyEx(b, cv2.MORPH_BLACKHAT, thin).take(at)) > LINE_GREY
    keep = inner & differs
    if dark.any():
        lines = np.zeros(candidates.shape, np.uint8)
        lines.flat[at] = dark
        lines = cv2.dilate(_long(lines, LINE_PX), np.ones(k, np.uint8))  # its blurred sides
        keep |= lines.take(at) > 0
    fg[sub].flat[at[keep]] = 255
    return fg


def _mean_std(grey: np.ndarray, k: tuple[int, int], at: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of `grey` (uint8) over a k window, at flat indices `at`."""
    mean = cv2.boxFilter(grey, cv2.CV_32F, k).take(at)
    square = cv2.sqrBoxFilter(grey, cv2.CV_32F, k).take(at)
    return mean, np.sqrt(np.maximum(square - mean * mean, 0.0))


def _long(mask: np.ndarray, length: int) -> np.ndarray:
    """The 8-connected pieces of `mask` (uint8) at least `length` pixels long (bounding box
    side), as a uint8 mask; labelled within the box around the mask's pixels."""
    x, y, w, h = cv2.boundingRect(mask)
    box = (slice(y, y + h), slice(x, x + w))
    # 16-bit labels (2-4x faster than 32-bit) whenever they cannot overflow: there are no
    # more pieces than pixels
    ltype = cv2.CV_16U if cv2.countNonZero(mask[box]) < 1 << 16 else cv2.CV_32S
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask[box], connectivity=8,
                                                           ltype=ltype)
    keep = (np.maximum(stats[:, 2], stats[:, 3]) >= length).astype(np.uint8)
    keep[0] = 0
    out = np.zeros_like(mask)
    out[box] = keep.take(labels)
    return out
