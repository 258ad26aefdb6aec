"""Detector stages after the background: the cleaned mask, recent motion, and the blobs that
look like vehicles."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from vtrack.boxes import centre, contains
from vtrack.errors import InputError

MOTION_GAP = 2    # frames between the two images of the motion check
MOTION_DIFF = 15  # max(|dB|, |dG|, |dR|) above which a pixel counts as changed


def _kernel(size: int) -> np.ndarray | None:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size)) if size > 1 else None


def load_roi(path: str, size: tuple[int, int]) -> np.ndarray:
    """A mask image (white = detect) resized to `size` (w, h), as 0/255."""
    if not Path(path).is_file():
        raise InputError(f"{path}: ROI mask not found")
    mask = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if mask is None:
        raise InputError(f"{path}: ROI mask is not a readable image")
    mask = cv2.resize(mask, size, interpolation=cv2.INTER_NEAREST)
    return np.where(mask >= 128, 255, 0).astype(np.uint8)


def polygon_mask(polygon: np.ndarray, size: tuple[int, int],
                 within: np.ndarray | None = None) -> np.ndarray:
    """0/255 mask of `size` (w, h), 255 inside `polygon` (n, 2, in that mask's pixels,
    pixel centres at integers), ANDed with `within` when given."""
    mask = np.zeros((size[1], size[0]), np.uint8)
    pts = np.round(np.asarray(polygon, dtype=float) * 16).astype(np.int32)   # 4 fraction bits
    cv2.fillPoly(mask, [pts], 255, lineType=cv2.LINE_8, shift=4)
    return mask if within is None else cv2.bitwise_and(mask, within)


class MaskCleaner:
    """Foreground mask -> binary mask: the ROI, then opening (removes speckle and leaf
    flicker) and closing (fills a vehicle's holes -- windows, a roof the colour of the
    road -- and joins its fragments)."""

    def __init__(self, roi: np.ndarray | None, open_kernel: int, close_kernel: int) -> None:
        self.roi = roi
        self._open, self._close = _kernel(open_kernel), _kernel(close_kernel)

    def __call__(self, fg: np.ndarray) -> np.ndarray:
        if self.roi is not None:
            fg = cv2.bitwise_and(fg, self.roi)
        if self._open is not None:
            fg = cv2.morphologyEx(fg, cv2.MORPH_OPEN, self._open)
        if self._close is not None:
            fg = cv2.morphologyEx(fg, cv2.MORPH_CLOSE, self._close)
        return fg


class MotionMap:
    """The pixels whose colour changed by more than MOTION_DIFF over the last MOTION_GAP
    frames. Colour, not grey: a red car on grey asphalt can have the asphalt's grey level."""

    def __init__(self) -> None:
        self._recent: deque[np.ndarray] = deque()  # the last MOTION_GAP prepared frames

    def __call__(self, small: np.ndarray) -> np.ndarray | None:
        """The changed pixels (0/1 uint8), or None while there is no older frame."""
        self._recent.append(small)
        if len(self._recent) <= MOTION_GAP:
            return None
        b, g, r = cv2.split(cv2.absdiff(small, self._recent.popleft()))
        diff = cv2.max(cv2.max(b, g), r)
        return cv2.threshold(diff, MOTION_DIFF, 1, cv2.THRESH_BINARY)[1]


@dataclass(frozen=True)
class BlobTests:
    """What a blob must pass to be a vehicle, in mask pixels: its pixel count the noise
    floor (`min_pixels`, or `floor` at its centre: sizes.SizeFloor), its area (the mask's
    pixel area `unit` in the video's pixels times its count) at least `min_area` and at
    most `max_area`, its fill ratio (count / box area: foliage blobs are ragged) at least
    `min_fill`, its width and height at least `least_side` at its centre (if given: a
    share of a vehicle's side there, sizes.SizeFloor.least_side), and with a motion map,
    something inside its box changed over the last frames (`min_motion` of the box:
    ghosts of vehicles present at the start are static) or it holds the centre of one of
    the `still` boxes (standing vehicles, hold.py)."""

    min_pixels: int
    min_area: float
    max_area: float
    min_fill: float
    min_motion: float
    unit: float = 1.0
    floor: Callable[[np.ndarray], np.ndarray] | None = None
    least_side: Callable[[np.ndarray], np.ndarray] | None = None   # per blob centre

    def __call__(self, stats: np.ndarray, moving: np.ndarray | None,
                 still: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """For blobs `stats` (N, 5: x, y, w, h, pixel count), whether each passes every test
        but the area cap (N,) and whether it is under the cap (N,)."""
        count = stats[:, 4]
        least = (self.min_pixels if self.floor is None
                 else self.floor(stats[:, :2] + stats[:, 2:4] / 2))
        ok = ((count >= least) & (count * self.unit >= self.min_area)
              & (count >= self.min_fill * stats[:, 2] * stats[:, 3]))
        if self.least_side is not None:
            side = self.least_side(stats[:, :2] + stats[:, 2:4] / 2)
            ok &= (stats[:, 2] >= side) & (stats[:, 3] >= side)
        if moving is not None:
            x0, y0, bw, bh = stats[:, :4].astype(np.int64).T
            x1, y1 = x0 + bw, y0 + bh
            changed = moving[y1, x1] - moving[y0, x1] - moving[y1, x0] + moving[y0, x0]
            moved = changed >= self.min_motion * bw * bh
            if still is not None and len(still):
                moved |= contains(np.column_stack([x0, y0, bw, bh]), centre(still)).any(1)
            ok &= moved
        return ok, count * self.unit <= self.max_area


def find_blobs(fg: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Outer contours of the mask and their stats (N, 5): bounding box x, y, w, h and
    pixel count (mask pixels).

    findContours is ~30x cheaper than connectedComponentsWithStats here; a blob's pixel
    count follows from its contour polygon by Pick's theorem, A + B/2 + 1 (holes filled).
    """
    contours, _ = cv2.findContours(fg, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    stats = np.array([(*cv2.boundingRect(c), cv2.contourArea(c) + len(c) / 2 + 1)
                      for c in contours], dtype=np.float64).reshape(-1, 5)
    return list(contours), stats


def kept_blobs(contours: list[np.ndarray], stats: np.ndarray, keep: np.ndarray, sx: float,
               sy: float) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The kept blobs' boxes (K, 4) and areas (K,) mapped to full resolution by the scale
    factors (sx, sy), and their contours (mask pixels)."""
    boxes = stats[keep, :4] * np.array([sx, sy, sx, sy])
    return (boxes.reshape(-1, 4), stats[keep, 4] * sx * sy,
            [c for c, k in zip(contours, keep, strict=True) if k])
