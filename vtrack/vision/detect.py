"""Moving-vehicle detector: MOG2 background subtraction -> cleaned mask -> blobs.

Per frame (all at the detection resolution, see `DetectorConfig.detect_width`):

1. downscale by a power of two (INTER_AREA) and blur lightly (sensor/JPEG noise);
2. gain compensation: scale each channel so the mean of the pixels that were background in
   the previous frame follows a slow running mean; auto-exposure swings (a global gain change
   faster than MOG2 can learn) would otherwise turn the whole road into foreground;
3. MOG2 (Zivkovic 2004/2006); its shadow label (127) and anything below
   `shadow_threshold` is dropped, then the ROI mask is applied;
4. morphology: open (speckle), close (holes, fragments of one vehicle);
5. connected components, kept if their area, size and fill ratio look like a vehicle and
   they do not sit in a "flicker" zone (swaying leaves, see `flicker_*`).

Boxes, centres and areas are mapped back to full-resolution pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from vtrack.errors import InputError


def _f(default, help_: str):
    return field(default=default, metadata={"help": help_})


@dataclass
class DetectorConfig:
    """MOG2 background-subtraction detector ([detector])."""

    history: int = _f(500, "MOG2 history: frames the background model remembers")
    var_threshold: float = _f(16.0, "MOG2 squared Mahalanobis distance for foreground")
    learning_rate: float = _f(-1.0, "MOG2 learning rate (-1: automatic, 1/history)")
    detect_shadows: bool = _f(True, "let MOG2 label shadows (127) so they can be dropped")
    shadow_ratio: float = _f(0.5, "MOG2 shadow threshold tau: darker than this is not shadow")
    shadow_threshold: int = _f(200, "mask values below this (MOG2 shadows are 127) are dropped")
    detect_width: int = _f(640, "frames wider than this are halved (INTER_AREA) until they "
                                "fit before detection; smaller frames are never shrunk")
    blur: int = _f(3, "Gaussian blur kernel before MOG2 (odd; 0 or 1: off)")
    gain_compensation: bool = _f(True, "cancel fast global brightness changes (auto-exposure)")
    open_kernel: int = _f(3, "opening kernel (detection pixels, 0: off): removes speckle")
    close_kernel: int = _f(7, "closing kernel (detection pixels, 0: off): joins fragments")
    min_area: float = _f(60.0, "smallest blob area, full-resolution pixels^2")
    max_area_fraction: float = _f(0.25, "largest blob area as a fraction of the frame")
    min_side: float = _f(4.0, "smallest blob width and height, full-resolution pixels")
    min_fill: float = _f(0.3, "smallest blob area / box area (ragged foliage is sparse)")
    flicker_rate: float = _f(0.0, "blobs whose pixels were foreground this often (0..1, "
                                  "running mean over ~1/flicker_alpha frames) are dropped; 0: off")
    flicker_alpha: float = _f(0.02, "update rate of the per-pixel foreground running mean")
    roi_mask: str = _f("", "optional mask image (white = detect), resized to the frame")
    warmup_frames: int = _f(15, "first frames only teach the background (no detections)")

    def validate(self) -> None:
        """Raise ValueError naming the first out-of-range field."""
        checks = {
            "history": self.history >= 1,
            "var_threshold": self.var_threshold > 0,
            "learning_rate": self.learning_rate < 0 or 0 <= self.learning_rate <= 1,
            "shadow_ratio": 0 < self.shadow_ratio < 1,
            "shadow_threshold": 1 <= self.shadow_threshold <= 255,
            "detect_width": self.detect_width >= 16,
            "blur": self.blur >= 0,
            "open_kernel": self.open_kernel >= 0,
            "close_kernel": self.close_kernel >= 0,
            "min_area": self.min_area >= 0,
            "max_area_fraction": 0 < self.max_area_fraction <= 1,
            "min_side": self.min_side >= 0,
            "min_fill": 0 <= self.min_fill <= 1,
            "flicker_rate": 0 <= self.flicker_rate <= 1,
            "flicker_alpha": 0 < self.flicker_alpha <= 1,
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
        self._roi = self._load_roi(cfg.roi_mask) if cfg.roi_mask else None
        self._open, self._close = _kernel(cfg.open_kernel), _kernel(cfg.close_kernel)
        self._ref: np.ndarray | None = None
        self._flicker = np.zeros(self._size[::-1], np.float32) if cfg.flicker_rate > 0 else None
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
        raw = self._mog.apply(small, learningRate=self.cfg.learning_rate)
        fg = self._clean(raw)
        self.foreground = fg
        self.frames += 1
        dets = Detections.empty() if self.frames <= self.cfg.warmup_frames else self._blobs(fg)
        if self._flicker is not None:
            cv2.accumulateWeighted(fg, self._flicker, self.cfg.flicker_alpha)
        return dets

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
        grey = cv2.cvtColor(small, cv2.COLOR_BGR2GRAY)
        coarse = cv2.resize(grey, (max(1, grey.shape[1] // 8), max(1, grey.shape[0] // 8)),
                            interpolation=cv2.INTER_AREA).astype(np.float32) + 1.0
        if self._ref is None:
            self._ref = coarse
            return small
        gain = float(np.clip(np.median(self._ref / coarse), 0.5, 2.0))
        self._ref += (gain * coarse - self._ref) / self.cfg.history
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

    def _blobs(self, fg: np.ndarray) -> Detections:
        n, labels, stats, _ = cv2.connectedComponentsWithStats(fg, connectivity=8)
        stats = stats[1:].astype(np.float64)
        x, y = stats[:, 0] * self._sx, stats[:, 1] * self._sy
        w, h = stats[:, 2] * self._sx, stats[:, 3] * self._sy
        area = stats[:, 4] * self._sx * self._sy
        cfg = self.cfg
        keep = ((area >= cfg.min_area)
                & (area <= cfg.max_area_fraction * self.width * self.height)
                & (w >= cfg.min_side) & (h >= cfg.min_side)
                & (area >= cfg.min_fill * w * h))
        if self._flicker is not None and keep.any():
            self.last_scores = self._flicker_score(labels, n)[keep]
            keep &= self._flicker_score(labels, n) < cfg.flicker_rate
        boxes = np.stack([x, y, w, h], axis=1)[keep]
        centers = boxes[:, :2] + boxes[:, 2:] / 2
        return Detections(centers, boxes, area[keep])

    def _flicker_score(self, labels: np.ndarray, n: int) -> np.ndarray:
        """Mean running foreground rate over each blob's pixels, (n - 1,)."""
        sums = np.bincount(labels.ravel(), weights=self._flicker.ravel(), minlength=n)
        counts = np.bincount(labels.ravel(), minlength=n)
        return (sums / np.maximum(counts, 1))[1:] / 255.0
