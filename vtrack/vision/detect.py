"""Moving-vehicle detector: one interface (`MotionDetector.detect`) over named stages:
prepare (prepare.py) -> stabilise (stabilise.py) -> background (background.py; optionally
not learning under standing vehicles, hold.py) -> shadows (shadows.py) -> shift tolerance
(jitter.py) -> blobs (blobs.py; optionally a noise floor in vehicle units, sizes.py, and
the blobs read against the predicted boxes, pieces.py) -> split (split.py; optionally at
their necks, necks.py, and by the expected footprint, footprint.py); optionally (hybrid,
`far_band`) the far end of a perspective view searched again at full resolution by a
second detector of this kind (far.py). docs/DETECTOR.md describes each stage and its
switch.
`detect` is `locate(segment(image))`: `segment` runs the image stages, which need no track
state, and returns what they found (`Foreground`); `locate` runs the blob stages on it,
which divide merged blobs among the tracker's predictions.

Per frame, at the detection resolution (frames wider than `detect_width` are halved until
they fit: MOG2 costs ~10x decoding at full HD resolution):

1. INTER_AREA downscale and a 3x3 Gaussian blur (sensor and codec noise);
2. gain compensation: the frame is scaled by the median ratio of a slow reference to it on
   a coarse grid, which cancels auto-exposure swings (the highway clip's mean grey moves
   between 95 and 116 within seconds, faster than MOG2 learns) and ignores vehicles;
3. MOG2 (Zivkovic 2004, 2006) with a variance floor `var_min` = 16 (sigma >= 4 grey
   levels; OpenCV's floor of 4 lets H.264 texture refreshes light up foliage), learning
   fast during the warm-up and at 1 / history afterwards (see `Mog2Background.learning_rate`);
4. MOG2's shadow label (127) is dropped (`shadow_threshold`), then the ROI mask is applied;
   on a camera that sways, foreground that a shift of the background by up to
   `shift_radius` px explains (an edge lit up by what the stabiliser leaves of the sway) is
   dropped (jitter.py);
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
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from typing import Any

import cv2
import numpy as np

from vtrack.boxes import centre
from vtrack.vision.background import Mog2Background, estimate_background
from vtrack.vision.blobs import (BlobTests, MaskCleaner, MotionMap, find_blobs, kept_blobs,
                                 load_roi, polygon_mask)
from vtrack.vision.changed import ChangedMap
from vtrack.vision.far import (FAR_LAG, FAR_SAMPLE_SECONDS, FAR_SAMPLES, FAR_SHARE,
                              FAR_SIDE_SHARE, Band, band_coef, far_band, most_rows,
                              seam_keep)
from vtrack.vision.hold import StandingBoxes, held_foreground, hold_mask
from vtrack.vision.footprint import split_long
from vtrack.vision.ghosts import StaticForeground
from vtrack.vision.jitter import ShiftTolerance
from vtrack.vision.necks import split_necks
from vtrack.vision.pieces import explained, group_pieces, matched
from vtrack.vision.prepare import FramePreparer, GainCompensator, downscale_factor
from vtrack.vision.sizes import SizeFloor
from vtrack.vision.shadows import drop_shadows, textured_shadow
from vtrack.vision.split import holders, split_blob
from vtrack.vision.stabilise import (IDENTITY, Following, Stabiliser, border_edges_kept,
                                     compose, invert, onto_mask, rescale, transform_boxes)

Pieces = tuple[np.ndarray, np.ndarray]   # a blob's pieces: boxes (n, 4), pixel counts (n,)
NO_PIECES: Pieces = (np.zeros((0, 4)), np.zeros(0))
HOLD_LAG = 2   # frames between the predicted boxes a frame holds and the frame
KINDS = ("hybrid", "mog2", "appearance")   # [detector] kind (vision/hybrid.py)

__all__ = ["DetectorConfig", "Detections", "Foreground", "MotionDetector", "downscale_factor"]


def _f(default: Any, help_: str) -> Any:
    """A dataclass field with a default and its documentation (printed in the TOML)."""
    return field(default=default, metadata={"help": help_})


@dataclass
class DetectorConfig:
    """The detector ([detector]): MOG2 background subtraction, an appearance model, or both
    fused (hybrid.py)."""

    kind: str = _f("hybrid", "which detector: \"mog2\" (background subtraction alone: "
                             "moving vehicles), \"appearance\" (the appearance model "
                             "alone, every frame) or \"hybrid\" (MOG2 blobs every frame, "
                             "fused with appearance boxes: standing, queued and merged "
                             "vehicles; docs/DETECTOR.md)")
    appearance_model: str = _f("", "a YOLOX-format ONNX model (COCO classes); empty: the "
                                   "YOLOX-Nano shipped inside vtrack")
    appearance_seconds: float = _f(0.1, "hybrid: the appearance model looks at the whole "
                                        "frame every this many seconds of video (every "
                                        "frame of a video slower than 1 / this; between "
                                        "passes the boxes of vehicles that stand are "
                                        "held)")
    appearance_tiles: bool = _f(False, "hybrid: half-way between two whole-frame passes "
                                      "the model looks at one tile of the frame in turn "
                                      "(the fewest overlapping tiles that magnify it 1.75 "
                                      "times), for the far vehicles the whole frame shows "
                                      "too small; false: whole-frame passes only")
    far_band: bool = _f(False, "hybrid: where the vehicles tracked so far say vehicles look "
                              "small at the detection resolution (the far end of a "
                              "perspective view of a frame wider than detect_width), a "
                              "second MOG2 detector searches those rows at full "
                              "resolution, its noise floor in vehicle units (far.py)")
    appearance_score: float = _f(0.3, "smallest appearance score (objectness x class) "
                                      "kept")
    appearance_alone_score: float = _f(0.4, "hybrid: smallest appearance score of a box no "
                                            "motion blob supports (a standing vehicle): "
                                            "one source of evidence, not two (fusion.py)")
    history: int = _f(500, "MOG2 history: frames the background model remembers")
    var_threshold: float = _f(16.0, "MOG2 squared Mahalanobis distance for foreground")
    var_min: float = _f(16.0, "MOG2 floor on a pixel's variance (grey levels^2): codec and "
                              "sensor noise (OpenCV's default 4 flickers on compressed video)")
    learning_rate: float = _f(-1.0, "MOG2 learning rate, 0..1 (negative: MOG2's fast start "
                                     "1 / (2 n) during the warm-up, then 1 / history)")
    detect_shadows: bool = _f(True, "let MOG2 label shadows (127): those whose texture is "
                                     "the road's are dropped, textured ones (dark vehicle "
                                     "parts) kept (shadows.py)")
    shadow_texture: float = _f(0.5, "a shadow-labelled pixel whose local texture (5x5 std) "
                                    "differs from the background's dimmed by the shadow by "
                                    "more than this fraction is a vehicle's (shadows.py); "
                                    "0: drop every shadow-labelled pixel")
    shadow_ratio: float = _f(0.5, "MOG2 shadow threshold tau: darker than this is not shadow")
    shadow_threshold: int = _f(200, "mask values below this (MOG2 shadows are 127) are dropped")
    shift_tolerance: float = _f(8.0, "once the camera has moved (stabilise), drop "
                                      "foreground pixels within this many grey levels, in "
                                      "every channel, of a blend of two adjacent background "
                                      "pixels within `shift_radius`: edges lit up by the "
                                      "sway the stabiliser leaves; 0: off (jitter.py)")
    shift_radius: int = _f(2, "how far (detection pixels) that shift may reach")
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
    max_area_fraction: float = _f(0.25, "largest blob area as a fraction of the frame (1: no "
                                        "cap; a truck near the camera can fill a quarter of "
                                        "it: docs/DETECTOR.md, measured)")
    min_fill: float = _f(0.4, "smallest blob area / box area (ragged foliage is sparse)")
    min_motion: float = _f(0.02, "smallest share of a blob's box that changed over the last "
                                 "2 frames; static blobs (ghosts of vehicles present at the "
                                 "start, stopped vehicles) are dropped; 0: off")
    roi_mask: str = _f("", "optional mask image (white = detect), resized to the frame")
    warmup_frames: int = _f(15, "first frames only teach the background (no detections), "
                                "unless the background was estimated from the video")
    init_background_seconds: float = _f(6.0, "estimate the background from frames sampled "
                                             "over the first this many seconds of a file "
                                             "(background.py), so that vehicles in view in "
                                             "the first frame are detected; 0: off")
    init_background_samples: int = _f(25, "frames sampled for that estimate")
    init_background_tolerance: int = _f(12, "grey levels (every channel) within which a "
                                            "sample counts as the same colour for that "
                                            "estimate (background.py)")
    init_background_support: float = _f(0.0, "for dense traffic: where under this share "
                                              "of the samples lie within the tolerance of "
                                              "their median, take their mode (the most "
                                              "frequent colour: the road between the "
                                              "vehicles of a platoon) instead; 0.5 for a "
                                              "carriageway full in the first seconds; 0: "
                                              "the median everywhere (background.py)")
    stabilise: bool = _f(True, "estimate the camera's sway per frame (similarity transform "
                               "against a reference frame) and warp frames onto it before "
                               "background subtraction; the tracker shifts its tracks by the "
                               "same motion. Switches itself off on a still camera")
    split_merged: bool = _f(True, "divide a blob that holds the predicted boxes of several "
                                  "tracked vehicles among them (split.py)")
    stabilise_robust: bool = _f(False, "for views that large vehicles fill: the "
                                       "stabiliser keeps only features that follow the "
                                       "camera's last motion, takes them from the "
                                       "background estimated from the video, and holds "
                                       "its last estimate for up to 1 s while vehicles "
                                       "hide them, and a blob cut by the reference's "
                                       "border stays on this frame's (stabilise.py); "
                                       "off: features of the first frame, RANSAC over "
                                       "all of them")
    stabilise_still_px: float = _f(0.5, "a camera whose image corners move less than this "
                                         "(detection pixels) over the first 2 s is still")
    stabilise_recheck_seconds: float = _f(1.0, "a still camera's motion is estimated once "
                                               "every this many seconds, and the "
                                               "stabiliser switches back on when it moved "
                                               "twice in a row (wind, a knock; "
                                               "stabilise.py); 0: never")
    hold_standing: bool = _f(False, "selective update: MOG2 does not learn the pixels under "
                                    "the predicted boxes of tracked vehicles that stand "
                                    "(hold.py), so a queued vehicle stays foreground and "
                                    "leaves no ghost when it drives off")
    hold_speed: float = _f(0.5, "a predicted box moving slower than this (box scales/s) "
                                "stands")
    hold_min_seconds: float = _f(0.2, "a box is held once it has stood this long")
    hold_max_seconds: float = _f(60.0, "and at most this long (then MOG2 learns it)")
    min_vehicle_share: float = _f(0.0, "noise floor in vehicle units: where the tracked "
                                       "vehicles' boxes say vehicles look small (far away), "
                                       "a blob of this share of a vehicle's expected area "
                                       "there is kept even under min_pixels (sizes.py); 0: "
                                       "min_pixels everywhere")
    min_vehicle_side: float = _f(0.0, "noise floor in vehicle units: a blob narrower or "
                                      "shorter than this share of a vehicle's expected "
                                      "side at its place is dropped (sizes.py; foliage "
                                      "slivers, edges); 0: off")
    min_pixels_far: int = _f(24, "the floor never falls below this (detection pixels)")
    split_footprint: bool = _f(False, "a blob longer than 2 vehicles at its place (the "
                                      "scale field learnt from the tracked boxes, "
                                      "sizes.py) that no tracked vehicle's predicted box "
                                      "matches is cut where it narrows to a waist "
                                      "(footprint.py)")
    static_seconds: float = _f(0.0, "foreground that has not changed for this long (s) "
                                    "is a ghost (of a vehicle in the estimated "
                                    "background, or one that stood and left) and is "
                                    "dropped from the mask, except under held standing "
                                    "vehicles (ghosts.py); 0: off")
    group_pieces: bool = _f(False, "the pieces of one tracked vehicle (a uniform-colour "
                                   "truck with holes), none of which would pass the "
                                   "blob tests alone, are joined into one blob inside "
                                   "its predicted box before the tests (pieces.py)")
    split_necks: bool = _f(False, "a blob pinched into several bodies of a similar width "
                                  "(two vehicles side by side seen obliquely, touching at "
                                  "a corner) is split at the necks of its distance "
                                  "transform (necks.py)")
    area_cap_tracked: bool = _f(False, "max_area_fraction drops only blobs that no "
                                       "tracked vehicle's predicted box explains (IoU >= "
                                       "0.5, or holding several: split): a truck driving "
                                       "up to the camera stays detected, a blob no "
                                       "vehicle could make is rejected (pieces.py)")

    def validate(self) -> None:
        """Raise ValueError naming the first out-of-range field."""
        if self.kind not in KINDS:
            raise ValueError(f"detector.kind must be \"hybrid\", \"mog2\" or "
                             f"\"appearance\", not {self.kind!r}")
        checks = {
            "appearance_seconds": self.appearance_seconds >= 0,
            "appearance_score": 0 < self.appearance_score <= 1,
            "appearance_alone_score": 0 <= self.appearance_alone_score <= 1,
            "history": self.history >= 1,
            "var_threshold": self.var_threshold > 0,
            "var_min": self.var_min > 0,
            "learning_rate": self.learning_rate <= 1,
            "shadow_ratio": 0 < self.shadow_ratio < 1,
            "shadow_texture": self.shadow_texture >= 0,
            "shadow_threshold": 1 <= self.shadow_threshold <= 255,
            "shift_tolerance": 0 <= self.shift_tolerance <= 255,
            "shift_radius": self.shift_radius >= 1,
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
            "init_background_seconds": self.init_background_seconds >= 0,
            "init_background_samples": self.init_background_samples >= 3,
            "init_background_tolerance": 0 <= self.init_background_tolerance <= 255,
            "init_background_support": 0 <= self.init_background_support <= 1,
            "stabilise_still_px": self.stabilise_still_px >= 0,
            "stabilise_recheck_seconds": self.stabilise_recheck_seconds >= 0,
            "hold_speed": self.hold_speed > 0,
            "min_vehicle_share": self.min_vehicle_share >= 0,
            "min_vehicle_side": 0 <= self.min_vehicle_side <= 1,
            "min_pixels_far": self.min_pixels_far >= 1,
            "static_seconds": self.static_seconds >= 0,
            "hold_min_seconds": self.hold_min_seconds >= 0,
            "hold_max_seconds": self.hold_max_seconds >= self.hold_min_seconds,
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
    # (2, 3) camera motion: maps the previous frame's pixels onto this frame's
    motion: np.ndarray = field(default_factory=lambda: IDENTITY.copy())
    # the share of any box that MOG2 saw change (changed.py); None without a frame
    changed: ChangedMap | None = None
    # (K,) provenance (fusion.py: 0 motion, 1 appearance, 2 both), score (1 for motion
    # blobs), class (index into appearance.VEHICLE_CLASSES, -1 unknown); None: all motion
    source: np.ndarray | None = None
    score: np.ndarray | None = None
    cls: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.areas)
        if self.source is None:
            self.source = np.zeros(n, dtype=int)
        if self.score is None:
            self.score = np.ones(n)
        if self.cls is None:
            self.cls = np.full(n, -1, dtype=int)

    def __len__(self) -> int:
        return len(self.areas)

    @property
    def seen(self) -> np.ndarray:
        """(K,) the boxes the appearance model drew: whole vehicles."""
        return self.source > 0

    @staticmethod
    def empty(motion: np.ndarray | None = None) -> Detections:
        """No blobs."""
        return Detections(np.zeros((0, 2)), np.zeros((0, 4)), np.zeros(0),
                          IDENTITY.copy() if motion is None else motion)


@dataclass
class Aligned:
    """One frame after the detector's first image stages (`MotionDetector.align`)."""

    image: np.ndarray           # at the detection resolution, on the reference, gain-corrected
    own: bool                   # `image` is the detector's to keep (not the caller's array)
    motion: np.ndarray          # (2, 3) camera motion: the previous frame -> this one
    camera: np.ndarray          # (2, 3) the stabiliser's reference -> this frame
    moved: bool                 # the camera has moved so far (shift tolerance runs)
    far: Aligned | None = None  # the far band's rows at full resolution (far.py)


@dataclass
class Foreground:
    """One frame after the detector's image stages (`MotionDetector.segment`)."""

    mask: np.ndarray            # cleaned foreground (0/255) at the detection resolution
    labels: np.ndarray          # MOG2's raw mask (0 / 127 shadow / 255) before the cleaning
    moving: np.ndarray | None   # what changed over the last 2 frames (blobs.MotionMap)
    motion: np.ndarray          # (2, 3) camera motion: the previous frame -> this one
    camera: np.ndarray          # (2, 3) the stabiliser's reference -> this frame
    learning: bool              # still in the warm-up: no detections yet
    held: np.ndarray | None = None   # (K, 4) standing boxes MOG2 did not learn (mask px)
    far: Foreground | None = None    # the far band's (far.py)


class MotionDetector:
    """MOG2 detector for one video of a fixed frame size; call `detect` once per frame."""

    def __init__(self, cfg: DetectorConfig, width: int, height: int, fps: float = 25.0,
                 roi: np.ndarray | None = None, far: bool = False,
                 roi_image: np.ndarray | None = None,
                 field: np.ndarray | None = None,
                 stabiliser: Stabiliser | Following | None = None) -> None:
        """`roi`: the region of interest, a polygon (n, 2) in frame pixels; foreground
        outside it (and outside `cfg.roi_mask`, or `roi_image`: a 0/255 mask of the
        frame's size that replaces it) is ignored. `far`: search the far band at full
        resolution once the scale field shows one (far.py). `field`: a fixed scale field
        (sizes.SizeFloor) for the noise floor in vehicle units (the far band's). `stabiliser`:
        one to use instead of this detector's own (the far band's follows the first
        detector's)."""
        cfg.validate()
        self.cfg = cfg
        self.fps, self.roi = fps, roi
        self.width, self.height = width, height
        self.prepare = FramePreparer(width, height, cfg.detect_width, cfg.blur)
        self.scale = self.prepare.scale
        size = self.prepare.size
        self._sx, self._sy = width / size[0], height / size[1]
        self.gain = GainCompensator(cfg.history) if cfg.gain_compensation else None
        self.background = Mog2Background(cfg.history, cfg.var_threshold, cfg.var_min,
                                         cfg.detect_shadows, cfg.shadow_ratio,
                                         cfg.learning_rate, cfg.warmup_frames)
        if roi_image is not None:
            mask = cv2.resize(roi_image, size, interpolation=cv2.INTER_NEAREST)
        else:
            mask = load_roi(cfg.roi_mask, size) if cfg.roi_mask else None
        if roi is not None:
            mask = polygon_mask(roi / (self._sx, self._sy), size, mask)
        self.clean = MaskCleaner(mask, cfg.open_kernel, cfg.close_kernel)
        self.shifted = (ShiftTolerance(cfg.shift_tolerance, cfg.shift_radius)
                        if cfg.shift_tolerance > 0 and cfg.stabilise else None)
        self.motion = MotionMap() if cfg.min_motion > 0 or cfg.static_seconds > 0 else None
        self.ghosts = (StaticForeground(max(1, round(cfg.static_seconds * fps)))
                       if cfg.static_seconds > 0 else None)
        if stabiliser is None and cfg.stabilise:
            stabiliser = Stabiliser(*size, probe_frames=max(1, round(2.0 * fps)),
                                    still_px=cfg.stabilise_still_px,
                                    recheck_frames=round(cfg.stabilise_recheck_seconds * fps),
                                    robust=cfg.stabilise_robust,
                                    hold_frames=round(fps) if cfg.stabilise_robust else 0)
        self.stabiliser = stabiliser
        self._camera = IDENTITY.copy()   # reference -> current frame, full resolution
        self.standing = (StandingBoxes(cfg.hold_speed, fps, round(cfg.hold_min_seconds * fps),
                                       round(cfg.hold_max_seconds * fps))
                         if cfg.hold_standing else None)
        # boxes to hold by the number of the located frame they came from: frame k holds
        # those of frame k - HOLD_LAG, which `locate` has handed over even when `segment`
        # runs a frame ahead in another thread (app/track.py), so results do not depend on
        # the threads' timing
        self._held: dict[int, np.ndarray] = {}
        self._located = 0
        # the scale field learnt from the predicted boxes: the noise floor in vehicle
        # units (sizes.py) and the expected footprint (footprint.py)
        self.far_wanted = far and self.scale > 1
        self.sizes = (SizeFloor(*size, cfg.min_vehicle_share, cfg.min_pixels_far,
                                cfg.min_pixels, field, cfg.min_vehicle_side)
                      if cfg.min_vehicle_share > 0 or cfg.min_vehicle_side > 0
                      or cfg.split_footprint or self.far_wanted else None)
        self.tests = BlobTests(cfg.min_pixels, cfg.min_area,
                               cfg.max_area_fraction * width * height, cfg.min_fill,
                               cfg.min_motion, self._sx * self._sy,
                               self.sizes if cfg.min_vehicle_share > 0 else None,
                               self.sizes.least_side if cfg.min_vehicle_side > 0 else None)
        self.foreground: np.ndarray | None = None
        # the far band (far.py): fixed by `locate`, searched from frame `_far_from` on
        self.band: Band | None = None
        self.far: MotionDetector | None = None
        self._far_from: int | None = None
        self._aligned = 0
        # until the band is fixed, the rows it may take, aligned, every `_sample_every`
        # frames: the band's background is estimated from them (far.py)
        self._sampling = self.far_wanted
        self._samples: deque[tuple[int, np.ndarray]] = deque(maxlen=FAR_SAMPLES)
        self._sample_every = max(1, round(FAR_SAMPLE_SECONDS * fps))
        self._sample_rows = (most_rows(size[1], self._sy, height, cfg.min_pixels)
                             if self.far_wanted else 0)
        self._follow = (Following(self.stabiliser, self._sx, self._sy)
                        if self.far_wanted and isinstance(self.stabiliser, Stabiliser)
                        else None)

    @property
    def frames(self) -> int:
        """Frames seen so far."""
        return self.background.frames

    def close(self) -> None:
        """Nothing to release (the fused detector stops its worker here)."""

    def in_roi(self, points: np.ndarray) -> np.ndarray:
        """(n,) whether each point (n, 2) of the frame (pixels) lies in the region of
        interest (everywhere without one)."""
        roi = self.clean.roi
        if roi is None or not len(points):
            return np.ones(len(points), dtype=bool)
        h, w = roi.shape[:2]
        u = np.clip((points[:, 0] / self._sx).astype(int), 0, w - 1)
        v = np.clip((points[:, 1] / self._sy).astype(int), 0, h - 1)
        return roi[v, u] > 0

    def initialise(self, images: Iterable[np.ndarray], prepared: bool = False,
                   aligned: bool = False) -> None:
        """Start the background model from `images` (frames sampled across the first
        seconds of the video, aligned onto the stabiliser's reference; `prepared`: already
        at the detection resolution, `prepare`d; `aligned`: already on the stabiliser's
        reference, as the far band's samples are): their median (with
        `init_background_support`, their mode where few of them are near the median:
        background.estimate_background); detection then starts with the first frame."""
        samples = []
        for image in images:
            small = image if prepared else self.prepare(image)
            if self.stabiliser is not None and not aligned:
                small = self.stabiliser.align(small)
            samples.append(small)
        if len(samples) < 3:
            return
        cfg = self.cfg
        background = estimate_background(samples, cfg.init_background_tolerance,
                                         cfg.init_background_support)
        if self.stabiliser is not None and cfg.stabilise_robust:
            self.stabiliser.set_reference(background)  # features on the static scene
        if self.gain is not None:
            background = self.gain(background)
        self.background.initialise(background)

    def detect(self, image: np.ndarray, predicted: np.ndarray | None = None) -> Detections:
        """Update the background with `image` (HxWx3 BGR uint8) and return its blobs:
        `locate(segment(image), predicted)`."""
        return self.locate(self.segment(image), predicted)

    def segment(self, image: np.ndarray, prepared: bool = False) -> Foreground:
        """The image stages (prepare, stabilise, gain, MOG2, shadows, shift tolerance,
        morphology, motion map) of the next frame, in frame order; they need no track
        state. `prepared`: `image` is already `prepare`d (and the detector's to keep).
        `subtract(align(image, prepared))`: the two halves keep separate state, so
        `align` of one frame may run beside `subtract` of the one before (app/track.py)."""
        return self.subtract(self.align(image, prepared))

    def align(self, image: np.ndarray, prepared: bool = False) -> Aligned:
        """The first image stages of the next frame, in frame order: prepare, stabilise,
        gain compensation."""
        self._aligned += 1
        small = image if prepared else self.prepare(image)
        motion = IDENTITY
        if self.stabiliser is not None:
            small, m = self.stabiliser(small)
            camera = rescale(m, self._sx, self._sy)
            motion = compose(camera, invert(self._camera))
            self._camera = camera
        if self.gain is not None:
            small = self.gain(small)
        moved = self.stabiliser is not None and self.stabiliser.moved
        return Aligned(small, prepared or small is not image, motion, self._camera, moved,
                       self._far_band(image, prepared))

    def _far_band(self, image: np.ndarray, prepared: bool) -> Aligned | None:
        """The far band's rows of the frame `image`, aligned by the band's detector once
        it has started (its background estimated from the samples on its first frame);
        before, every `_sample_every`-th frame's rows it may take, kept as a sample."""
        if self._far_from is not None and self._aligned >= self._far_from:
            if prepared:
                raise ValueError("the far band needs the full-resolution frame")
            rows = self.band.rows
            if self._aligned == self._far_from:
                self.far.initialise([crop[:rows] for number, crop in self._samples
                                     if number < self._far_from], aligned=True)
                self._samples.clear()
            return self.far.align(image[:rows])
        if self._sampling and not prepared and self._aligned % self._sample_every == 0:
            crop = image[:self._sample_rows]
            self._samples.append((self._aligned, crop.copy() if self._follow is None
                                  else self._follow(crop)[0]))
        return None

    def subtract(self, aligned: Aligned) -> Foreground:
        """The other image stages of the next aligned frame, in frame order: MOG2 (with the
        standing boxes held), shadows, shift tolerance, motion map, ghosts, morphology."""
        cfg = self.cfg
        small = aligned.image
        held_boxes = self._held.pop(self.frames + 1 - HOLD_LAG, None)
        held = hold_mask(held_boxes, small.shape[:2]) if held_boxes is not None else None
        raw = self.background.apply(small, held)
        if held is not None:
            inside = held_foreground(small, self.background.image(), held, cfg.var_threshold,
                                     cfg.var_min, cfg.shadow_ratio, cfg.detect_shadows)
            raw = cv2.bitwise_or(cv2.bitwise_and(raw, cv2.bitwise_not(held)), inside)
        if cfg.detect_shadows and cfg.shadow_texture > 0:
            fg = textured_shadow(raw, small, self.background.image(), cfg.shadow_texture)
        else:
            fg = drop_shadows(raw, cfg.shadow_threshold)
        if self.shifted is not None and aligned.moved:  # only with a stabiliser
            fg = self.shifted(fg, small, self.background.image())
        changed = (self.motion(small if aligned.own else small.copy())
                   if self.motion is not None else None)
        if self.ghosts is not None:
            fg = self.ghosts(fg, changed, held)
        self.foreground = self.clean(fg)
        moving = cv2.integral(changed) if changed is not None and cfg.min_motion > 0 else None
        learning = self.frames <= cfg.warmup_frames and not self.background.primed
        return Foreground(self.foreground, raw, moving, aligned.motion, aligned.camera,
                          learning, held_boxes, self._far_subtract(aligned.far))

    def _far_subtract(self, far: Aligned | None) -> Foreground | None:
        """The far band detector's image stages of its aligned rows, if it has started."""
        return self.far.subtract(far) if far is not None else None

    def locate(self, fg: Foreground, predicted: np.ndarray | None = None) -> Detections:
        """The blobs of a segmented frame, in its pixels.

        `predicted`, when given, holds the tracked vehicles' predicted boxes (K, 4) in this
        frame's pixels (the tracker's prediction with the camera's motion `fg.motion`): a
        blob holding several of them is divided among them (split.py)."""
        cfg = self.cfg
        predicted = np.zeros((0, 4)) if predicted is None else predicted
        self._located += 1
        on_mask = onto_mask(predicted, fg.camera, self._sx, self._sy)   # the mask's pixels
        if self.standing is not None:
            self._held[self._located] = self.standing(on_mask)
        if self.sizes is not None:
            self.sizes.add(on_mask)
            if self.far_wanted and self.band is None and self.sizes.coef is not None:
                self._start_far_band()
        if fg.learning:
            return Detections.empty(fg.motion)
        contours, stats = find_blobs(fg.mask)
        ok, small = self.tests(stats, fg.moving, fg.held)
        if (cfg.group_pieces or cfg.area_cap_tracked) and len(predicted) and len(stats):
            contours, stats, ok, small = self._pieces(contours, stats, ok, small, fg,
                                                      on_mask)
        boxes, areas, contours = kept_blobs(contours, stats, ok & small, self._sx, self._sy)
        whole = np.arange(len(boxes))   # the blob each row still is whole (-1: a piece)
        if cfg.split_merged and len(boxes) and len(predicted) >= 2:
            boxes, areas, whole = self._split(boxes, areas, contours, on_mask)
        if cfg.split_necks and len(boxes):
            boxes, areas, whole = self._necks(boxes, areas, contours, whole)
        if cfg.split_footprint and len(boxes) and self.sizes.coef is not None:
            boxes, areas = self._footprint(boxes, areas, contours, whole, on_mask)
        ref_boxes, boxes = boxes, transform_boxes(fg.camera, boxes)  # -> this frame's pixels
        if cfg.stabilise_robust:   # the fit follows the camera: the sway is a few pixels
            boxes = border_edges_kept(ref_boxes, boxes, self.width, self.height)
        if fg.far is not None:
            boxes, areas = self._with_far_band(boxes, areas, fg.far, predicted)
        return Detections(centre(boxes), boxes, areas, fg.motion,
                          ChangedMap(fg.labels, self._sx, self._sy, fg.camera))

    def _start_far_band(self) -> None:
        """Fix the far band from the scale field's first fit (far.py), if the view has one:
        its detector, on the band's rows at full resolution, sees frames from FAR_LAG
        frames on."""
        mask_height = self.prepare.size[1]
        band = far_band(self.sizes.coef, mask_height, self._sy, self.height,
                        self.cfg.min_pixels)
        self.far_wanted = False   # fixed once
        if band is None:
            self._sampling = False
            self._samples.clear()
            return
        cfg = replace(self.cfg, detect_width=self.width, min_vehicle_share=FAR_SHARE,
                      min_vehicle_side=FAR_SIDE_SHARE,
                      roi_mask="", shift_radius=self.cfg.shift_radius * self.scale)
        roi_image = None
        if self.cfg.roi_mask:
            roi_image = load_roi(self.cfg.roi_mask, (self.width, self.height))[:band.rows]
        self.band = band
        self.far = MotionDetector(cfg, self.width, band.rows, self.fps, self.roi,
                                  roi_image=roi_image,
                                  field=band_coef(self.sizes.coef, self._sy, mask_height,
                                                  band.rows),
                                  stabiliser=self._follow)
        self._far_from = self._located + FAR_LAG

    def _with_far_band(self, boxes: np.ndarray, areas: np.ndarray, far: Foreground,
                       predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The blobs (frame pixels) with those above the far band's seam replaced by the
        band detector's (far.py)."""
        band = self.far.locate(far, predicted)
        keep, keep_far = seam_keep(boxes, band.boxes, self.band)
        return (np.concatenate([boxes[keep], band.boxes[keep_far]]),
                np.concatenate([areas[keep], band.areas[keep_far]]))

    def _pieces(self, contours: list[np.ndarray], stats: np.ndarray, ok: np.ndarray,
                small: np.ndarray, fg: Foreground, pred: np.ndarray
                ) -> tuple[list[np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
        """The blobs and their tests read against the predicted boxes `pred` (all in mask
        pixels): pieces of one vehicle joined, blobs over the area cap that a predicted box
        explains passed (pieces.py)."""
        cfg = self.cfg
        if cfg.group_pieces:
            n = len(stats)
            contours, stats = group_pieces(contours, stats, ok & small, pred)
            if len(stats) != n:
                ok, small = self.tests(stats, fg.moving, fg.held)
        if cfg.area_cap_tracked and not small.all():
            large = np.flatnonzero(ok & ~small)
            small = small.copy()
            small[large] = explained(stats[large, :4], pred, *fg.mask.shape[::-1])
        return contours, stats, ok, small

    def _divided(self, boxes: np.ndarray, areas: np.ndarray, whole: np.ndarray,
                 cut: Callable[[int], Pieces]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The blobs (full resolution, reference pixels) with each row replaced by its
        pieces where `cut(row)` returns some (boxes (n, 4) and pixel counts (n,) in mask
        pixels); also which blob each row still is, whole (`whole`; -1: a piece)."""
        scale = np.array([self._sx, self._sy, self._sx, self._sy])
        out_b, out_a, out_w = [], [], []
        for row, (box, area, w) in enumerate(zip(boxes, areas, whole, strict=True)):
            pieces, counts = cut(row)
            if len(pieces):
                out_b.append(pieces * scale)
                out_a.append(counts * self._sx * self._sy)
                out_w.append(np.full(len(pieces), -1))
            else:
                out_b.append(box[None])
                out_a.append(np.array([area]))
                out_w.append(np.array([w]))
        return np.concatenate(out_b), np.concatenate(out_a), np.concatenate(out_w)

    def _split(self, boxes: np.ndarray, areas: np.ndarray, contours: list[np.ndarray],
               pred: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Blobs (full resolution, reference pixels) holding several predicted boxes `pred`
        (mask pixels) replaced by their pieces (split.py). Also returns for each row the
        blob it is, whole (-1: a piece)."""
        scale = np.array([self._sx, self._sy, self._sx, self._sy])

        def cut(row: int) -> Pieces:
            held = holders(boxes[row] / scale, pred)
            if len(held):
                pieces, counts = split_blob(contours[row], pred[held], self.cfg.min_pixels // 2)
                if len(pieces) >= 2:
                    return pieces, counts
            return NO_PIECES

        return self._divided(boxes, areas, np.arange(len(boxes)), cut)

    def _necks(self, boxes: np.ndarray, areas: np.ndarray, contours: list[np.ndarray],
               whole: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Whole blobs (rows of `whole` >= 0: their contour's index) replaced by their
        bodies when they pinch at a neck (necks.py); `whole` after it."""
        return self._divided(boxes, areas, whole, lambda row: (
            split_necks(contours[whole[row]], self.cfg.min_pixels // 2)
            if whole[row] >= 0 else NO_PIECES))

    def _footprint(self, boxes: np.ndarray, areas: np.ndarray, contours: list[np.ndarray],
                   whole: np.ndarray, pred: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Whole blobs (rows of `whole` >= 0: their contour's index; full resolution,
        reference pixels) longer than the vehicles at their place, and which no predicted
        box `pred` (mask pixels) matches, replaced by their pieces cut at the waists
        (footprint.py)."""
        scale = np.array([self._sx, self._sy, self._sx, self._sy])
        side = self.sizes.side(centre(boxes / scale))
        tracked = matched(boxes / scale, pred, *self.prepare.size)
        boxes, areas, _ = self._divided(boxes, areas, whole, lambda row: (
            split_long(contours[whole[row]], side[row], self.cfg.min_pixels // 2)
            if whole[row] >= 0 and not tracked[row] else NO_PIECES))
        return boxes, areas
