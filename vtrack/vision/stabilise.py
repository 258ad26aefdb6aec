"""Detector stage: camera motion compensation.

A camera on a pole or a bridge sways and vibrates: a shift of one or two pixels lights up
every lane marking and kerb in the background model. The stage estimates, per frame, the
similarity transform M (rotation, scale, translation) that maps a fixed reference frame onto
the current one -- Lucas-Kanade optical flow of corner features of the reference, RANSAC fit
(estimateAffinePartial2D) -- and warps the frame back onto the reference, so the background
model sees a still scene. Against a fixed reference (not frame to frame) the estimate does not
drift. If the reference is lost (too few inliers: the view changed too much), the current
frame becomes the reference, placed where the last estimate put the previous frame, so the
output coordinates stay the same (`reanchored` counts these).

Static cameras pay almost nothing after the probe: if M stays within `still_px` of the
identity at the image corners over the first `probe_frames` frames, the stage switches
itself off, and estimates M only once every `recheck_frames` frames; a camera found moved
then (wind, a knock on the pole) by more than RECHECK_FACTOR x `still_px` at two checks in a
row switches it back on. (On still real cameras the checks' estimates scatter up to 0.84 px
at 640x360, fooled by the vehicles; one check over 0.5 px switched the stage on by mistake
and cost a count.)

`robust` (the detector's `stabilise_robust`, off by default) is for views that large
vehicles fill. Without it, where vehicles carry most of the reference's features (a side view
with a van across it, a truck passing under a bridge camera) RANSAC fits the vehicles'
motion and the estimate runs off with them (on the scene suite's side views 16 and 65 px
off the true sway on average). With it:
- each feature's flow is seeded with the last estimate and kept only if it lands within
  FOLLOW_PX (estimation pixels) of where that estimate puts it: the sway changes little
  from one frame to the next, a vehicle crossing the feature does not follow it;
- the reference is the background estimated from the video (the detector passes it to
  `set_reference`), whose features lie on the static scene, not the first frame's vehicles;
  the frames sampled for that background, seconds apart, are each aligned onto the first
  by the fit seeded at the identity or, where the unseeded fit disagrees with it, by the
  one whose warp matches the first frame better (`align`);
- any fit of MIN_INLIERS consistent features counts (vehicles hide most features at times);
- a lost frame keeps the last transform, for up to `hold_frames` frames, before the
  current frame becomes the reference;
- the detector moves a blob's edge that lay on the reference's border onto this frame's
  (`border_edges_kept`): with the sway right, the two borders are a few pixels apart, and
  the tracker reads only an edge on the image border as cut. (Without `robust` the estimate
  can be tens of pixels off on such views, and the move would stretch boxes by as much.)
"""

from __future__ import annotations

import cv2
import numpy as np

from vtrack.boxes import on_border

IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
STILL_WARP_PX = 0.25  # a transform moving no image corner further than this is no motion
MIN_INLIERS = 12      # fewest RANSAC inliers of a fit
FOLLOW_PX = 3.0       # robust: how far (estimation px) a feature may land from the last fit
AGREE_PX = 0.5        # robust align: two fits this close (estimation px) agree
RECHECK_FACTOR = 2.0  # a still camera's recheck: moved beyond this x still_px
RECHECKS_MOVED = 2    # ... at this many checks in a row


def corner_shift(M: np.ndarray, width: int, height: int) -> float:
    """Largest displacement (px) of the image corners under the 2x3 transform M."""
    c = np.array([[0, 0], [width, 0], [0, height], [width, height]], dtype=float)
    return float(np.abs(c @ M[:, :2].T + M[:, 2] - c).max())


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The 2x3 transform of applying b, then a."""
    return np.hstack([a[:, :2] @ b[:, :2], (a[:, :2] @ b[:, 2] + a[:, 2])[:, None]])


def invert(m: np.ndarray) -> np.ndarray:
    """The inverse of a 2x3 affine transform."""
    return cv2.invertAffineTransform(m)


def rescale(m: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """M in pixels scaled by (sx, sy): S M S^-1 with S = diag(sx, sy)."""
    S = np.array([sx, sy])
    return np.hstack([m[:, :2] * S[:, None] / S[None, :], (m[:, 2] * S)[:, None]])


def transform_boxes(m: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Axis-aligned boxes (x, y, w, h) mapped by M: the bounding boxes of their corners."""
    if len(boxes) == 0 or np.array_equal(m, IDENTITY):
        return boxes
    x0, y0 = boxes[:, 0], boxes[:, 1]
    x1, y1 = x0 + boxes[:, 2], y0 + boxes[:, 3]
    cx = np.stack([x0, x1, x0, x1], axis=1)
    cy = np.stack([y0, y0, y1, y1], axis=1)
    u = m[0, 0] * cx + m[0, 1] * cy + m[0, 2]
    v = m[1, 0] * cx + m[1, 1] * cy + m[1, 2]
    lo = np.stack([u.min(axis=1), v.min(axis=1)], axis=1)
    hi = np.stack([u.max(axis=1), v.max(axis=1)], axis=1)
    return np.hstack([lo, hi - lo])


def onto_mask(boxes: np.ndarray, camera: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """Boxes (x, y, w, h) in a frame's pixels mapped into the detection mask's: back through
    the stabiliser's `camera` (reference -> that frame, full resolution) and down by the
    full-resolution pixels (sx, sy) per mask pixel."""
    return transform_boxes(invert(camera), boxes) / np.array([sx, sy, sx, sy])


def border_edges_kept(ref_boxes: np.ndarray, boxes: np.ndarray, width: int, height: int
                      ) -> np.ndarray:
    """`boxes`, the reference's boxes `ref_boxes` (x, y, w, h) mapped into this frame, with
    each edge that lay on the reference picture's border moved to this frame's border: the
    warped picture's edge is the image's, and a vehicle cut there goes on beyond it (the
    tracker reads an edge on the image border as cut; a sway of a few pixels would
    otherwise leave it 1-3 px inside)."""
    if len(boxes) == 0:
        return boxes
    size = np.array([width, height], dtype=float)
    lo, hi = boxes[:, :2], boxes[:, :2] + boxes[:, 2:]
    cut = on_border(ref_boxes, width, height)
    lo = np.where(cut[:, :, 0], np.minimum(lo, 0.0), lo)
    hi = np.where(cut[:, :, 1], np.maximum(hi, size), hi)
    return np.hstack([lo, hi - lo])


class Stabiliser:
    """Per frame: (the frame warped onto the reference, M reference -> current frame)."""

    def __init__(self, width: int, height: int, probe_frames: int, still_px: float,
                 est_width: int = 320, robust: bool = False, hold_frames: int = 0,
                 recheck_frames: int = 0) -> None:
        self.width, self.height = width, height
        self.s = max(1.0, width / est_width)          # estimation at <= est_width pixels
        self.est_size = (max(1, round(width / self.s)), max(1, round(height / self.s)))
        self.probe_frames, self.still_px = probe_frames, still_px
        self.recheck_frames = recheck_frames   # 0: a still camera is never looked at again
        self._rechecks_moved = 0               # consecutive rechecks that found it moved
        self.robust, self.hold_frames = robust, hold_frames
        self._held = 0                 # consecutive lost frames held on the last transform
        self.active = True
        self.frames = 0
        self.max_shift = 0.0
        self.reanchored = 0
        self.M = IDENTITY.copy()
        self._base = IDENTITY.copy()   # the first reference -> the current reference
        self._ref: np.ndarray | None = None
        self._pts: np.ndarray | None = None
        self._last = IDENTITY.copy()   # the last fit, reference -> frame, estimation px
        self.applied = IDENTITY        # the last frame's M as returned

    @property
    def moved(self) -> bool:
        """Whether the camera has moved by more than `still_px` so far."""
        return self.max_shift > self.still_px

    def _grey(self, small: np.ndarray) -> np.ndarray:
        g = cv2.cvtColor(small, cv2.COLOR_BGR2GRAY)
        return g if self.s == 1 else cv2.resize(g, self.est_size, interpolation=cv2.INTER_AREA)

    def set_reference(self, small: np.ndarray) -> None:
        """Make `small` (a frame at the detection resolution) the reference."""
        self._ref = self._grey(small)
        self._last = IDENTITY.copy()
        pts = cv2.goodFeaturesToTrack(self._ref, 200, 0.01, 10, blockSize=7)
        self._pts = pts if pts is not None else np.zeros((0, 1, 2), np.float32)

    def estimate(self, small: np.ndarray, guess: np.ndarray | None = None
                 ) -> np.ndarray | None:
        """M (2x3, detection pixels) mapping the reference onto `small`, or None when the
        reference is lost. `robust`: the features' flows start at `guess` (M in estimation
        pixels; the last fit when None) and only those landing within FOLLOW_PX of it
        count."""
        if self._ref is None:
            self.set_reference(small)
            return IDENTITY.copy()
        if len(self._pts) < MIN_INLIERS:
            return None
        grey = self._grey(small)
        start = (cv2.transform(self._pts, self._last if guess is None else guess)
                 if self.robust else None)
        m = self._fit(grey, start)
        if m is None:
            return None
        if guess is None:
            self._last = m.copy()
        m[:, 2] *= self.s  # estimation pixels -> detection pixels (the linear part is unchanged)
        return m

    def _fit(self, grey: np.ndarray, start: np.ndarray | None) -> np.ndarray | None:
        """The similarity transform (estimation pixels) of the reference's features tracked
        into `grey` by Lucas-Kanade and RANSAC, or None. With `start` (the features' seeded
        places) only features landing within FOLLOW_PX of it count and any MIN_INLIERS
        consistent ones make a fit; unseeded, a quarter of the features must agree."""
        if start is None:
            nxt, status, _ = cv2.calcOpticalFlowPyrLK(self._ref, grey, self._pts, None,
                                                      winSize=(15, 15), maxLevel=3)
            ok = status.ravel() == 1
            least = max(MIN_INLIERS, 0.25 * len(self._pts))
        else:
            nxt, status, _ = cv2.calcOpticalFlowPyrLK(
                self._ref, grey, self._pts, start.astype(np.float32), winSize=(15, 15),
                maxLevel=3, flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
            ok = ((status.ravel() == 1)
                  & (np.abs(nxt - start).reshape(-1, 2).max(axis=1) <= FOLLOW_PX))
            least = MIN_INLIERS
        if ok.sum() < MIN_INLIERS:
            return None
        m, inliers = cv2.estimateAffinePartial2D(self._pts[ok], nxt[ok], method=cv2.RANSAC,
                                                 ransacReprojThreshold=1.0)
        return None if m is None or inliers.sum() < least else m

    def _residual(self, grey: np.ndarray, m: np.ndarray) -> float:
        """Median absolute grey difference between the reference and `grey` warped back
        onto it by m (estimation pixels): small where m is the camera's motion, whatever
        the vehicles do."""
        return float(np.median(cv2.absdiff(_resample(grey, m), self._ref)))

    def align(self, small: np.ndarray) -> np.ndarray:
        """`small` warped onto the reference (the first frame aligned becomes it), without
        counting it as a frame of the video.

        Robust: the frames sampled for the background lie seconds apart, so the camera may
        have moved further than FOLLOW_PX from the reference; of the fit seeded at the
        identity and the unseeded one, the seeded where they agree (within AGREE_PX), else
        the one whose warp matches the reference better (seeded alone, a frame the camera
        had moved far from went into the background unaligned)."""
        if not self.robust or self._ref is None:
            m = self.estimate(small, IDENTITY)
            return small if m is None else _warp(small, m)
        if len(self._pts) < MIN_INLIERS:
            return small
        grey = self._grey(small)
        seeded = self._fit(grey, self._pts)       # seeded at the identity
        plain = self._fit(grey, None)
        if seeded is None or plain is None:
            m = plain if seeded is None else seeded
        elif np.abs(seeded - plain).max() < AGREE_PX:
            m = seeded
        else:
            m = min((seeded, plain), key=lambda f: self._residual(grey, f))
        if m is None:
            return small
        m[:, 2] *= self.s
        return _warp(small, m)

    def __call__(self, small: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(small warped onto the reference, M reference -> current) for the next frame."""
        warped, self.applied = self._step(small)
        return warped, self.applied

    def _step(self, small: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.frames += 1
        if not self.active:
            if not self._moved_since(small):
                return small, IDENTITY
            self.active = True       # the camera started moving
        m = self.estimate(small)
        if m is None and self._held < self.hold_frames:
            self._held += 1          # robust: vehicles hide the features for a while
            return self._output(small, self.M)
        self._held = 0
        if m is None:
            # Lost (the view changed too much for the reference's features): this frame
            # becomes the reference, placed where the last estimate put the previous one,
            # so the output coordinates -- and the background model -- stay the same.
            self._base = self.M
            self.set_reference(small)
            self.reanchored += 1
            m = IDENTITY.copy()
        m = compose(m, self._base)
        self.M = m
        self.max_shift = max(self.max_shift, corner_shift(m, self.width, self.height))
        if self.frames >= self.probe_frames and self.max_shift <= self.still_px:
            self.active = False  # a still camera: nothing to compensate
        return self._output(small, m)

    def _moved_since(self, small: np.ndarray) -> bool:
        """Whether a camera found still has moved: at RECHECKS_MOVED checks in a row (every
        `recheck_frames`-th frame), M moved an image corner further than RECHECK_FACTOR x
        `still_px` (a lost reference is no evidence either way)."""
        if not self.recheck_frames or self.frames % self.recheck_frames:
            return False
        m = self.estimate(small)
        moved = m is not None and corner_shift(compose(m, self._base), self.width,
                                               self.height) > RECHECK_FACTOR * self.still_px
        self._rechecks_moved = self._rechecks_moved + 1 if moved else 0
        return self._rechecks_moved >= RECHECKS_MOVED

    def _output(self, small: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if corner_shift(m, self.width, self.height) <= STILL_WARP_PX:
            return small, IDENTITY   # below what resampling could represent: no motion
        return _warp(small, m), m


class Following:
    """The stabiliser of a detector on the top rows of the same frames at (sx, sy) times
    another's resolution (the far band, far.py): the other's `leader` estimate of each
    frame, rescaled, rather than an estimate of its own. Called after the leader on each
    frame."""

    def __init__(self, leader: Stabiliser, sx: float, sy: float) -> None:
        self.leader, self.sx, self.sy = leader, sx, sy

    @property
    def moved(self) -> bool:
        """Whether the camera has moved so far (the leader's finding)."""
        return self.leader.moved

    def __call__(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(image warped onto the reference, M reference -> current) by the leader's M of
        the same frame."""
        m = rescale(self.leader.applied, self.sx, self.sy)
        return _warp(image, m), m


def _warp(small: np.ndarray, m: np.ndarray) -> np.ndarray:
    """`small` resampled onto the reference by M (reference -> small); unchanged when M
    moves no corner by more than a quarter pixel (resampling blurs more than that moves)."""
    h, w = small.shape[:2]
    return small if corner_shift(m, w, h) <= STILL_WARP_PX else _resample(small, m)


def _resample(image: np.ndarray, m: np.ndarray) -> np.ndarray:
    """`image` resampled onto the reference by M (reference -> image), bilinear."""
    h, w = image.shape[:2]
    return cv2.warpAffine(image, m, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE)
