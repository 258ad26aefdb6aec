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
    fg = np.where(raw == 255, np.uint8(255), np.uint8(0))
    candidates = raw == SHADOW
    if not candidates.any():
        return fg
    k = (window, window)
    # Only the region around the shadow-labelled pixels is examined.
    x, y, w, h = cv2.boundingRect(candidates.astype(np.uint8))
    m = window
    x0, y0 = max(x - m, 0), max(y - m, 0)
    x1, y1 = min(x + w + m, raw.shape[1]), min(y + h + m, raw.shape[0])
    sub = (slice(y0, y1), slice(x0, x1))
    candidates = candidates[sub]
    f = cv2.cvtColor(frame[sub], cv2.COLOR_BGR2GRAY).astype(np.float32)
    b = cv2.cvtColor(background[sub], cv2.COLOR_BGR2GRAY).astype(np.float32)
    mf, mb = cv2.blur(f, k), cv2.blur(b, k)
    sf = np.sqrt(np.maximum(cv2.blur(f * f, k) - mf * mf, 0.0))
    sb = np.sqrt(np.maximum(cv2.blur(b * b, k) - mb * mb, 0.0))
    ratio = mf / (mb + 1.0)
    expected = ratio * sb
    differs = np.abs(sf - expected) > np.maximum(texture * expected, NOISE_GREY)
    # Blurred edges -- the ring around a vehicle's outline, the rim of a shadow -- mix two
    # brightness levels and look textured: only pixels with shadow-labelled neighbours all
    # round are judged (the closing fills a vehicle's holes again).
    inner = cv2.erode(candidates.astype(np.uint8), np.ones(k, np.uint8)) > 0
    # Thin dark lines -- a vehicle's outline, window frames, the gap under a bumper -- one or
    # two pixels wide; a shadow has none of its own, only the road's dimmed: the 3x3
    # black-hat (closing minus image) of the frame above r times the background's.
    thin = np.ones((3, 3), np.uint8)
    lines = (cv2.morphologyEx(f, cv2.MORPH_BLACKHAT, thin)
             - ratio * cv2.morphologyEx(b, cv2.MORPH_BLACKHAT, thin)) > LINE_GREY
    lines = _long(lines & candidates, LINE_PX)
    lines = cv2.dilate(lines.astype(np.uint8), np.ones(k, np.uint8)) > 0  # its blurred sides
    fg[sub][candidates & ((inner & differs) | lines)] = 255
    return fg


def _long(mask: np.ndarray, length: int) -> np.ndarray:
    """The 8-connected pieces of `mask` at least `length` pixels long (bounding box side)."""
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    keep = np.maximum(stats[:, 2], stats[:, 3]) >= length
    keep[0] = False
    return keep[labels]
