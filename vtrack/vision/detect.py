"""Moving-vehicle detector: MOG2 background subtraction -> cleaned mask -> blobs.

Per frame, at the detection resolution (frames wider than `detect_width` are halved until
they fit: MOG2 costs ~10x decoding at full HD resolution):

1. INTER_AREA downscale and a 3x3 Gaussian blur (sensor and codec noise);
2. gain compensation: the frame is scaled by the median ratio of a slow reference to it on
   a coarse grid, which cancels auto-exposure swings (the highway clip's mean grey moves
   between 95 and 116 within seconds, faster than MOG2 learns) and ignores vehicles;
3. MOG2 (Zivkovic 2004, 2006) with a variance floor `var_min` = 16 (sigma >= 4 grey
   levels; OpenCV's floor of 4 lets H.264 texture refreshes light up foliage), learning
   fast during the warm-up and at 1 / history afterwards (see `_learning_rate`);
4. MOG2's shadow label (127) is dropped (`shadow_threshold`), then the ROI mask is applied;
5. morphology: opening (3x3) removes speckle and leaf flicker, then closing (7x7) fills a
   vehicle's holes (windows, a roof the colour of the road) and joins its fragments;
6. outer contours, kept when their area and fill ratio (area / box area: foliage blobs are
   ragged) look like a vehicle and something inside their box moved over the last two
   frames (`min_motion`: ghosts left by vehicles present at the start are static). The
   noise floor `min_pixels` counts detection pixels, so it means the same for a 320x240
   and a downscaled 1920x1080 video; `min_area` is in the video's own pixels.

Defaults were tuned on the real clips in ../shared/videos and synthetic clips. Known
limits: hard shadows that MOG2 does not label (much darker than the road) stay attached to
their vehicle and can join it to a neighbour; vehicles far away whose colour matches the
road appear as outlines and are often missed; a grey car slightly darker than the road is
labelled shadow (`detect_shadows = false` finds it, at the price of shadow blobs).

Boxes, centres and areas are mapped back to full-resolution pixels.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from vtrack.errors import InputError


MOTION_GAP = 2    # frames between the two images of the motion check
MOTION_DIFF = 15  # max(|dB|, |dG|, |dR|) above which a pixel counts as changed


def _f(default: Any, help_: str) -> Any:
    """A dataclass field with a default and its documentation (printed in the TOML)."""
    return field(default=default, metadata={"help": help_})


@dataclass
class DetectorConfig:
    """MOG2 background-subtraction detector ([detector])."""

    history: int = _f(500, "MOG2 history: frames the background model remembers")
    var_threshold: float = _f(16.0, "MOG2 squared Mahalanobis distance for foreground")
    var_min: float = _f(16.0, "MOG2 floor on a pixel's variance (grey levels^2): codec and "
                              "sensor noise (OpenCV's default 4 flickers on compressed video)")
    learning_rate: float = _f(-1.0, "MOG2 learning rate, 0..1 (negative: MOG2's fast start "
                                     "1 / (2 n) during the warm-up, then 1 / history)")
    detect_shadows: bool = _f(False, "let MOG2 label shadows (127) so they can be dropped")
    shadow_ratio: float = _f(0.5, "MOG2 shadow threshold tau: darker than this is not shadow")
    shadow_threshold: int = _f(200, "mask values below this (MOG2 shadows are 127) are dropped")
    detect_width: int = _f(640, "frames wider than this are halved (INTER_AREA) until they "
                                "fit before detection; smaller frames are never shrunk")
    blur: int = _f(3, "Gaussian blur kernel before MOG2 (odd; 0 or 1: off)")
    gain_compensation: bool = _f(True, "cancel fast global brightness changes (auto-exposure)")
    open_kernel: int = _f(3, "opening kernel (detection pixels, 0: off): removes speckle")
    close_kernel: int = _f(7, "closing kernel (detection pixels, 0: off): joins fragments")
    min_pixels: int = _f(150, "smallest blob in pixels at the detection resolution: the noise "
                              "floor, the same for any video size")
    min_area: float = _f(0.0, "smallest blob area in the video's own (full-resolution) "
                              "pixels^2, on top of min_pixels")
    max_area_fraction: float = _f(0.25, "largest blob area as a fraction of the frame")
    min_fill: float = _f(0.4, "smallest blob area / box area (ragged foliage is sparse)")
    min_motion: float = _f(0.02, "smallest share of a blob's box that changed over the last "
                                 "2 frames; static blobs (ghosts of vehicles present at the "
                                 "start, stopped vehicles) are dropped; 0: off")
    roi_mask: str = _f("", "optional mask image (white = detect), resized to the frame")
    warmup_frames: int = _f(15, "first frames only teach the background (no detections)")

    def validate(self) -> None:
        """Raise ValueError naming the first out-of-range field."""
        checks = {
            "history": self.history >= 1,
            "var_threshold": self.var_threshold > 0,
            "var_min": self.var_min > 0,
            "learning_rate": self.learning_rate <= 1,
            "shadow_ratio": 0 < self.shadow_ratio < 1,
            "shadow_threshold": 1 <= self.shadow_threshold <= 255,
            "detect_width": self.detect_width >= 16,
            "blur": self.blur >= 0,
            "open_kernel": self.open_kernel >= 0,
            "close_kernel": self.close_kernel >= 0,
            "min_pixels": self.min_pixels >= 1,
            "min_area": self.min_area >= 0,
            "max_area_fraction": 0 < self.max_area_fraction <= 1,
            "min_fill": 0 <= self.min_fill <= 1,
            "min_motion": 0 <= self.min_motion <= 1,
            "warmup_frames": self.warmup_frames >= 0,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"detector.{name} out of range: {getattr(self, name)!r}")


@dataclass
class Detections:
    """Blobs of one frame in full-resolution pixels (OpenCV 0-based origin)."""

    centers: np.ndarray  # (K, 2) box centres x, y
    boxes: np.ndarray    # (K, 4) x, y, w, h
    areas: np.ndarray    # (K,) foreground pixel count, px^2

    def __len__(self) -> int:
        return len(self.areas)

    @staticmethod
    def empty() -> Detections:
        """No blobs."""
        return Detections(np.zeros((0, 2)), np.zeros((0, 4)), np.zeros(0))


def downscale_factor(width: int, detect_width: int) -> int:
    """Smallest power of two s with width / s <= detect_width (1 for small frames)."""
    s = 1
    while width / s > detect_width:
        s *= 2
    return s


def _kernel(size: int) -> np.ndarray | None:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size)) if size > 1 else None


class MotionDetector:
    """MOG2 detector for one video of a fixed frame size; call `detect` once per frame."""

    def __init__(self, cfg: DetectorConfig, width: int, height: int) -> None:
        cfg.validate()
        self.cfg = cfg
        self.width, self.height = width, height
        self.scale = downscale_factor(width, cfg.detect_width)
        self._size = (max(1, round(width / self.scale)), max(1, round(height / self.scale)))
        self._sx, self._sy = width / self._size[0], height / self._size[1]
        self._mog = cv2.createBackgroundSubtractorMOG2(cfg.history, cfg.var_threshold,
                                                       cfg.detect_shadows)
        self._mog.setShadowThreshold(cfg.shadow_ratio)
        self._mog.setVarMin(cfg.var_min)  # OpenCV keeps var_min <= var_init <= var_max
        self._mog.setVarInit(max(cfg.var_min, self._mog.getVarInit()))
        self._mog.setVarMax(max(5 * cfg.var_min, self._mog.getVarMax()))
        self._roi = self._load_roi(cfg.roi_mask) if cfg.roi_mask else None
        self._open, self._close = _kernel(cfg.open_kernel), _kernel(cfg.close_kernel)
        self._ref: np.ndarray | None = None
        self._recent: deque[np.ndarray] = deque()  # the last MOTION_GAP prepared frames
        self.frames = 0
        self.foreground: np.ndarray | None = None

    def _load_roi(self, path: str) -> np.ndarray:
        if not Path(path).is_file():
            raise InputError(f"{path}: ROI mask not found")
        mask = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        if mask is None:
            raise InputError(f"{path}: ROI mask is not a readable image")
        mask = cv2.resize(mask, self._size, interpolation=cv2.INTER_NEAREST)
        return np.where(mask >= 128, 255, 0).astype(np.uint8)

    def detect(self, image: np.ndarray) -> Detections:
        """Update the background with `image` (HxWx3 BGR uint8) and return its blobs."""
        small = self._prepare(image)
        self.frames += 1
        raw = self._mog.apply(small, learningRate=self._learning_rate())
        self.foreground = self._clean(raw)
        moving = self._motion(small if small is not image else image.copy())
        if self.frames <= self.cfg.warmup_frames:
            return Detections.empty()
        return self._blobs(self.foreground, moving)

    def _learning_rate(self) -> float:
        """MOG2's fast start (-1: 1 / (2 n)) during the warm-up, then the steady 1 / history.

        A mode holding 10 % of a pixel's weight counts as background, so at the fast rate a
        vehicle covering a pixel for more than 0.2 n frames melts into the background (long
        or slow vehicles, for hundreds of frames); at 1 / 500 that takes ~50 frames.
        """
        if self.cfg.learning_rate >= 0:
            return self.cfg.learning_rate
        return -1.0 if self.frames <= self.cfg.warmup_frames else 1.0 / self.cfg.history

    def _motion(self, small: np.ndarray) -> np.ndarray | None:
        """Integral image of the pixels whose colour changed by more than MOTION_DIFF over
        the last MOTION_GAP frames (None while there is no older frame, or when off).

        Colour, not grey: a red car on grey asphalt can have the asphalt's grey level.
        """
        if self.cfg.min_motion <= 0:
            return None
        self._recent.append(small)
        if len(self._recent) <= MOTION_GAP:
            return None
        b, g, r = cv2.split(cv2.absdiff(small, self._recent.popleft()))
        diff = cv2.max(cv2.max(b, g), r)
        return cv2.integral(cv2.threshold(diff, MOTION_DIFF, 1, cv2.THRESH_BINARY)[1])

    def _prepare(self, image: np.ndarray) -> np.ndarray:
        if image.shape[:2] != (self.height, self.width):
            raise ValueError(f"frame is {image.shape[1]}x{image.shape[0]}, detector expects "
                             f"{self.width}x{self.height}")
        small = image if self.scale == 1 else cv2.resize(image, self._size,
                                                         interpolation=cv2.INTER_AREA)
        if self.cfg.blur > 1:
            k = self.cfg.blur | 1
            small = cv2.GaussianBlur(small, (k, k), 0)
        if self.cfg.gain_compensation:
            small = self._compensate_gain(small)
        return small

    def _compensate_gain(self, small: np.ndarray) -> np.ndarray:
        """Scale `small` by the median ratio of a slow reference to it, on an 8x coarser grid.

        g = median(ref / frame) over the grid cells is robust to vehicles covering fewer than
        half of the cells; ref follows the compensated frames at MOG2's rate 1/history, so the
        reference and MOG2's model agree and only changes faster than MOG2 learns are removed.
        """
        h, w = small.shape[:2]
        coarse = cv2.resize(small, (max(1, w // 8), max(1, h // 8)), interpolation=cv2.INTER_AREA)
        coarse = cv2.cvtColor(coarse, cv2.COLOR_BGR2GRAY).astype(np.float32) + 1.0
        if self._ref is None:
            self._ref = coarse
            return small
        gain = float(np.clip(np.median(self._ref / coarse), 0.5, 2.0))
        self._ref += (gain * coarse - self._ref) / self.cfg.history
        if abs(gain - 1.0) < 0.002:  # under half a grey level: skip the full-frame pass
            return small
        return cv2.convertScaleAbs(small, alpha=gain)

    def _clean(self, raw: np.ndarray) -> np.ndarray:
        _, fg = cv2.threshold(raw, self.cfg.shadow_threshold - 1, 255, cv2.THRESH_BINARY)
        if self._roi is not None:
            fg = cv2.bitwise_and(fg, self._roi)
        if self._open is not None:
            fg = cv2.morphologyEx(fg, cv2.MORPH_OPEN, self._open)
        if self._close is not None:
            fg = cv2.morphologyEx(fg, cv2.MORPH_CLOSE, self._close)
        return fg

    def _blobs(self, fg: np.ndarray, moving: np.ndarray | None) -> Detections:
        """Outer contours of the mask, filtered, mapped to full resolution.

        findContours is ~30x cheaper than connectedComponentsWithStats here; a blob's pixel
        count follows from its contour polygon by Pick's theorem, A + B/2 + 1 (holes filled).
        `moving` (an integral image) gives the changed pixels in each box in O(1).
        """
        contours, _ = cv2.findContours(fg, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        if not contours:
            return Detections.empty()
        stats = np.array([(*cv2.boundingRect(c), cv2.contourArea(c) + len(c) / 2 + 1)
                          for c in contours], dtype=np.float64)
        x, y = stats[:, 0] * self._sx, stats[:, 1] * self._sy
        w, h = stats[:, 2] * self._sx, stats[:, 3] * self._sy
        area = stats[:, 4] * self._sx * self._sy
        cfg = self.cfg
        keep = ((stats[:, 4] >= cfg.min_pixels) & (area >= cfg.min_area)
                & (area <= cfg.max_area_fraction * self.width * self.height)
                & (area >= cfg.min_fill * w * h))
        if moving is not None:
            x0, y0, bw, bh = stats[:, :4].astype(np.int64).T
            x1, y1 = x0 + bw, y0 + bh
            changed = moving[y1, x1] - moving[y0, x1] - moving[y1, x0] + moving[y0, x0]
            keep &= changed >= cfg.min_motion * bw * bh
        boxes = np.stack([x, y, w, h], axis=1)[keep]
        centers = boxes[:, :2] + boxes[:, 2:] / 2
        return Detections(centers, boxes, area[keep])
