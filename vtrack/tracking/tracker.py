"""Multi-target vehicle tracker: one constant-acceleration Kalman filter per vehicle, all
stepped together as arrays through the shared core (vtrack.estimation.kalman).

Per frame: predict; join pieces of one vehicle; gate (Mahalanobis, k-d-tree candidates) and
assign (per connected group); resolve blobs shared by several tracks; let coasting tracks
re-acquire detections inside their boxes; update (Joseph form); start tentative tracks.

Lifecycle: tentative -> confirmed after `confirm_hits` hits in the last `confirm_window`
frames, once it has moved `confirm_motion` box diagonals (static clutter never does) ->
coasting on the prediction while detections are lost -> deleted after `max_coast_seconds`
without a detection (a tentative track after `tentative_misses` missed frames) or when its
predicted box has left the image. A track's rows from before
confirmation are reported at confirmation (so its start is not lost) and its id is assigned
then (ids have no gaps).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from vtrack.estimation.filters import GaussianFilter, make_filter
from vtrack.estimation.kalman import kf_predict, kf_update
from vtrack.estimation.models import ConstantAcceleration, position_measurement
from vtrack.tracking.association import assign, gated_pairs, nearest_pairs
from vtrack.tracking.measurements import finite_difference_measurement

ADAPTIVE_KINDS = ("ankf1", "ankf2", "fuzzy-r", "fuzzy-q", "siim-ekf")


def _h(text: str) -> dict:
    return {"help": text}


@dataclass
class TrackerConfig:
    """Tracker parameters ([tracker] in the TOML config)."""

    filter: str = field(default="kf", metadata=_h(
        "per-vehicle filter: 'kf' (all tracks stepped together as arrays, with the "
        "`measurement` below) or an adaptive kind of the core run per track on the position "
        "rows: 'ankf1', 'ankf2', 'fuzzy-r', 'fuzzy-q', 'siim-ekf'"))
    measurement: str = field(default="finite-difference", metadata=_h(
        "'finite-difference': position + finite-difference velocity and acceleration "
        "(seed 001 eqs. 24-26, H = I6); 'position': position only"))
    jerk_psd: float = field(default=1e4, metadata=_h(
        "white-jerk spectral density q_j of the constant-acceleration model, px^2/s^5"))
    detection_sigma: float = field(default=2.0, metadata=_h(
        "std of a detected centre, px (R of the position rows; the differences follow)"))
    init_speed_sigma: float = field(default=150.0, metadata=_h(
        "prior std of a new track's velocity, px/s"))
    init_accel_sigma: float = field(default=100.0, metadata=_h(
        "prior std of a new track's acceleration, px/s^2"))
    gate_probability: float = field(default=0.999, metadata=_h(
        "chi-square gate on the predicted position (2 dof)"))
    max_gate_px: float = field(default=80.0, metadata=_h(
        "upper bound of the gate's Euclidean radius, px"))
    confirm_hits: int = field(default=6, metadata=_h(
        "M of the M-of-N confirmation (a track's rows from before it are back-filled)"))
    confirm_window: int = field(default=8, metadata=_h("N of the M-of-N confirmation"))
    confirm_motion: float = field(default=0.3, metadata=_h(
        "a track is confirmed only once its detected centre has moved this many box "
        "diagonals from where it was first seen: a vehicle moves, swaying leaves and "
        "flicker stay put (0 turns the check off)"))
    max_coast_seconds: float = field(default=1.0, metadata=_h(
        "time a confirmed track coasts on its prediction without a detection before it is "
        "deleted, s (in time, not frames, so it means the same at 24 and 60 fps)"))
    tentative_misses: int = field(default=3, metadata=_h(
        "misses that delete a track not yet confirmed"))
    size_smoothing: float = field(default=0.5, metadata=_h(
        "weight of a detection that is larger than the track's box in the box size (0..1]"))
    max_size_growth: float = field(default=0.1, metadata=_h(
        "largest relative growth of a track's box per frame (plus the track's displacement, "
        "so a vehicle coming into view at the border can grow)"))
    size_shrink: float = field(default=0.05, metadata=_h(
        "weight of a smaller detection in the box size: small, because a vehicle partly "
        "hidden by an occluder or the image border looks smaller (0..1]"))
    split_evidence_px: float = field(default=8.0, metadata=_h(
        "a track whose box holds two pieces tells one vehicle cut by an occluder (the gap "
        "between the pieces stays put) from several vehicles (the gap moves with them) once "
        "it has moved this far since the pieces appeared, px"))
    edge_margin_px: float = field(default=0.0, metadata=_h(
        "a track is deleted once its whole predicted box is this far outside the image (a "
        "vehicle half out of view keeps its track: the nested-box measurement follows it)"))

    def validate(self) -> None:
        if self.filter not in ("kf",) + ADAPTIVE_KINDS:
            raise ValueError(f"tracker.filter must be one of kf, {', '.join(ADAPTIVE_KINDS)}")
        if self.measurement not in ("finite-difference", "position"):
            raise ValueError("tracker.measurement must be 'finite-difference' or 'position'")
        for name in ("jerk_psd", "detection_sigma", "init_speed_sigma", "init_accel_sigma",
                     "max_gate_px", "split_evidence_px"):
            if not getattr(self, name) > 0:
                raise ValueError(f"tracker.{name} must be positive")
        if not 0 < self.gate_probability < 1:
            raise ValueError("tracker.gate_probability must be in (0, 1)")
        if not 1 <= self.confirm_hits <= self.confirm_window <= 30:
            raise ValueError("tracker needs 1 <= confirm_hits <= confirm_window <= 30")
        if self.confirm_motion < 0:
            raise ValueError("tracker.confirm_motion must be >= 0")
        if self.max_coast_seconds < 0 or self.tentative_misses < 1:
            raise ValueError("tracker.max_coast_seconds >= 0 and tentative_misses >= 1")
        if not (0 < self.size_smoothing <= 1 and 0 < self.size_shrink <= 1):
            raise ValueError("tracker.size_smoothing and size_shrink must be in (0, 1]")


ROW_COLUMNS = ("frame", "id", "x", "y", "w", "h", "conf")  # conf 1 = detected, < 1 = coasted


@dataclass
class FrameTracks:
    """The confirmed tracks after one frame (arrays over tracks) and the rows it emits."""

    ids: np.ndarray            # (K,) track ids
    boxes: np.ndarray          # (K, 4) x, y, w, h clipped to the image
    coasted: np.ndarray        # (K,) True when no detection updated the track this frame
    states: np.ndarray         # (K, 6) posterior [x, y, vx, vy, ax, ay]
    covariances: np.ndarray    # (K, 6, 6)
    innovations: np.ndarray    # (K,) |position innovation| in px (nan when coasted)
    rows: np.ndarray           # (R, 7) ROW_COLUMNS to write (incl. rows back-filled later)
    detection_of: np.ndarray   # (K,) index of the detection used (-1 when coasted)
    size_rates: np.ndarray     # (K, 2) d(w, h)/dt of the box, px/s (0 while size is not filtered)


class Tracker:
    """Array-based multi-target tracker. Call `step(frame, t, centers, boxes)` every frame."""

    def __init__(self, cfg: TrackerConfig, width: int, height: int) -> None:
        cfg.validate()
        self.cfg = cfg
        self.width, self.height = width, height
        self.model = ConstantAcceleration(cfg.jerk_psd)
        self.gate = -2.0 * math.log1p(-cfg.gate_probability)  # chi-square quantile, 2 dof
        self.next_id = 1
        self.next_uid = 0
        self.t_prev: float | None = None
        n = 0
        self.x = np.zeros((n, 6))
        self.P = np.zeros((n, 6, 6))
        self.size = np.zeros((n, 2))
        self.hist_p = np.zeros((n, 3, 2))   # last three detected centres, newest first
        self.hist_t = np.zeros((n, 3))
        self.hist_s = np.zeros((n, 3, 2))   # their stds (see _nested_centre)
        self.origin = np.zeros((n, 2))      # the first detected centre
        self.count = np.zeros(n, dtype=int)  # detections so far (capped at 3 for the FDs)
        self.hitmask = np.zeros(n, dtype=np.int64)  # bit i: hit i frames ago
        self.misses = np.zeros(n, dtype=int)
        self.id = np.zeros(n, dtype=int)     # 0 while tentative
        self.uid = np.zeros(n, dtype=int)
        self.gap_p = np.full((n, 2), np.nan)  # where the gap between two pieces was first seen
        self.gap_t = np.full(n, np.nan)       # and when (nan: the track's box holds one piece)
        # Rows not yet final, by uid (_emit); a tentative track that never moves keeps only
        # its latest rows, so static clutter cannot grow memory without bound.
        self.pending: dict[int, deque[np.ndarray]] = {}
        # Adaptive kinds: one core filter object per track (by uid) on the position rows.
        self.filters: dict[int, GaussianFilter] | None = None if cfg.filter == "kf" else {}
        self._position = position_measurement(6, cfg.detection_sigma)

    # ----------------------------------------------------------------- helpers
    _KILLED = 1 << 40  # misses value that marks a duplicate track for deletion
    _MAX_PENDING = 4096  # rows kept for a track not yet confirmed (see pending)
    _arrays = ("x", "P", "size", "origin", "hist_p", "hist_t", "hist_s", "count", "hitmask",
               "misses", "id", "uid", "gap_p", "gap_t")

    def _keep(self, keep: np.ndarray) -> None:
        if self.filters is not None:
            for uid in self.uid[~keep]:
                del self.filters[int(uid)]
        for name in self._arrays:
            setattr(self, name, getattr(self, name)[keep])

    def _append(self, **values: np.ndarray) -> None:
        for name in self._arrays:
            setattr(self, name, np.concatenate([getattr(self, name), values[name]]))

    def __len__(self) -> int:
        return len(self.x)

    @property
    def max_row_lag(self) -> int:
        """Rows come out of `step` late (a tentative track's once it is confirmed, coasted
        ones once the vehicle is re-acquired), but never this many frames late: after
        `step(g)`, no row of a frame <= g - max_row_lag will come."""
        return self._MAX_PENDING + 1

    def boxes(self) -> np.ndarray:
        """Boxes (x, y, w, h) centred on the filtered positions, clipped to the image."""
        half = self.size / 2
        x0 = np.clip(self.x[:, 0] - half[:, 0], 0, self.width)
        y0 = np.clip(self.x[:, 1] - half[:, 1], 0, self.height)
        x1 = np.clip(self.x[:, 0] + half[:, 0], 0, self.width)
        y1 = np.clip(self.x[:, 1] + half[:, 1], 0, self.height)
        return np.stack([x0, y0, x1 - x0, y1 - y0], axis=1)

    # -------------------------------------------------------------------- step
    def step(self, frame: int, t: float, centers: np.ndarray, boxes: np.ndarray) -> FrameTracks:
        """Advance all tracks to time t (s) and assimilate this frame's detections."""
        cfg = self.cfg
        centers = np.asarray(centers, dtype=float).reshape(-1, 2)
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        dt = 0.0 if self.t_prev is None else t - self.t_prev
        self.t_prev = t
        if len(self) and dt > 0:
            if self.filters is None:
                F = self.model.transition(dt)
                self.x, self.P = kf_predict(self.x, self.P, F, self.model.Q(dt))
            else:
                for i, uid in enumerate(self.uid):
                    f = self.filters[int(uid)]
                    f.predict(dt)
                    self.x[i], self.P[i] = f.x, f.P

        centers, boxes, split = self._merge_fragments(t, centers, boxes)
        # Gate and assign on the predicted position.
        ti, di, cost = gated_pairs(
            self.x[:, :2], self.P[:, :2, :2], centers, self.gate, cfg.max_gate_px,
            lambda trk, det: self._nested_centre(trk, boxes[det]))
        mt, md = assign(ti, di, cost, len(self), len(centers))
        mt, md, consumed = self._resolve_shared(mt, md, boxes)
        mt, md = self._reacquire(mt, md, consumed, centers)

        self._update(mt, boxes[md], t, split[mt])
        hit = np.zeros(len(self), dtype=bool)
        hit[mt] = True
        self.hitmask = ((self.hitmask << 1) | hit) & ((1 << cfg.confirm_window) - 1)
        self.misses = np.where(hit, 0, self.misses + 1)
        innov = np.full(len(self), np.nan)
        innov[mt] = self._last_innov
        det_of = np.full(len(self), -1)
        det_of[mt] = md

        spawned = self._spawn(frame, t, centers, boxes, np.concatenate([md, consumed]))
        innov = np.concatenate([innov, np.full(spawned, np.nan)])
        det_of = np.concatenate([det_of, self._spawned_det])
        hit = np.concatenate([hit, np.ones(spawned, dtype=bool)])

        inside, alive = self._fate()
        rows = self._emit(frame, hit, inside, alive)
        keep = inside & alive
        self._keep(keep)
        hit, innov, det_of = hit[keep], innov[keep], det_of[keep]
        conf = self.id > 0
        return FrameTracks(ids=self.id[conf].copy(), boxes=self.boxes()[conf],
                           coasted=~hit[conf], states=self.x[conf].copy(),
                           covariances=self.P[conf].copy(), innovations=innov[conf],
                           rows=rows, detection_of=det_of[conf],
                           size_rates=np.zeros((int(conf.sum()), 2)))

    def _merge_fragments(self, t: float, centers: np.ndarray, boxes: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Detections whose centres all fall inside one confirmed track's predicted box (and in
        no other) are pieces of one vehicle cut by an occluder, or several vehicles the track
        has followed as one blob (a queue far from the camera) that have now come apart.

        The gap between the two largest pieces tells them apart: an occluder is static, so
        the gap stays where it first appeared while the vehicle moves on; the gap between two
        vehicles moves with them. Once the track has moved `split_evidence_px` since the
        pieces appeared, a gap that followed it by half that or more marks the track as
        split (its box then shrinks to the piece it takes, freeing the others to start
        tracks); until then, and for a static gap, the pieces are joined into their union.
        Pieces spanning more than 1.2 times the track's box are separate vehicles at once.
        Returns the detections and which tracks were split."""
        split = np.zeros(len(self), dtype=bool)
        conf = np.flatnonzero(self.id > 0)
        held = np.zeros(len(self), dtype=bool)
        if len(conf) and len(centers) >= 2:
            bi, di = points_in_boxes(centers, self.boxes()[conf])
            claims = np.bincount(di, minlength=len(centers))
            ok = claims[di] == 1
            bi, di = bi[ok], di[ok]
            per_box = np.bincount(bi, minlength=len(conf))
            keep = np.ones(len(centers), dtype=bool)
            boxes = boxes.copy()
            for b in np.flatnonzero(per_box >= 2):
                track, parts = conf[b], di[bi == b]
                held[track] = True
                x0 = boxes[parts, :2].min(axis=0)
                x1 = (boxes[parts, :2] + boxes[parts, 2:]).max(axis=0)
                apart = np.any(x1 - x0 > 1.2 * self.size[track])
                if apart or self._gap_moved(track, t, boxes[parts]):
                    split[track] = True
                    continue
                boxes[parts[0]] = [*x0, *(x1 - x0)]
                keep[parts[1:]] = False
            boxes = boxes[keep]
            centers = boxes[:, :2] + boxes[:, 2:] / 2
        self.gap_t[~held | split] = np.nan
        return centers, boxes, split

    def _gap_moved(self, track: int, t: float, pieces: np.ndarray) -> bool:
        """Whether the gap between the two largest `pieces` (x, y, w, h) has moved with the
        track since it first appeared (see _merge_fragments); records it when it is new."""
        a, b = pieces[np.argsort(pieces[:, 2] * pieces[:, 3])[-2:]]
        lo = np.minimum(a[:2] + a[2:], b[:2] + b[2:])   # per axis: the facing edges when the
        hi = np.maximum(a[:2], b[:2])                   # pieces are apart, else their overlap
        gap = (lo + hi) / 2
        if np.isnan(self.gap_t[track]):
            self.gap_p[track], self.gap_t[track] = gap, t
            return False
        travelled = np.hypot(*self.x[track, 2:4]) * (t - self.gap_t[track])
        if travelled < self.cfg.split_evidence_px:
            return False
        return bool(np.hypot(*(gap - self.gap_p[track])) >= 0.5 * travelled)

    def _reacquire(self, mt: np.ndarray, md: np.ndarray, consumed: np.ndarray,
                   centers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Second association stage: a track left without a detection takes a left-over
        detection whose centre lies inside its predicted box (nearest first).

        A track that coasted on a prediction spoilt by partial detections (an occluder) can
        drift out of its own gate while its vehicle is plainly inside its box; without this
        stage the detection could neither update the track nor start a new one. A tentative
        track takes part too: when the visible part of a vehicle jumps (entering behind an
        occluder), a second track on the same vehicle would otherwise start beside it."""
        waiting = self.misses < self._KILLED
        waiting[mt] = False
        lost = np.flatnonzero(waiting)
        if len(lost) == 0:
            return mt, md
        free = np.setdiff1d(np.arange(len(centers)), np.concatenate([md, consumed]))
        if len(free) == 0:
            return mt, md
        bi, pi = points_in_boxes(centers[free], self.boxes()[lost])
        if len(bi) == 0:
            return mt, md
        dist = np.linalg.norm(centers[free[pi]] - self.x[lost[bi], :2], axis=1)
        rt, rd = assign(bi, pi, dist, len(lost), len(free))
        return np.concatenate([mt, lost[rt]]), np.concatenate([md, free[rd]])

    def _resolve_shared(self, mt: np.ndarray, md: np.ndarray, boxes: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Detections whose box holds the predicted centres of two or more confirmed tracks.

        If those tracks' boxes largely overlap (the intersection covers over half of the
        smaller box), they follow one vehicle: the oldest track takes the detection and the
        younger ones are deleted. Otherwise the detection is a merged blob of several
        vehicles: its centroid belongs to none of them, so those tracks coast instead of being
        pulled toward the middle, and the blob is consumed (it starts no track).
        Returns the pairs and the consumed detections.
        """
        consumed: list[int] = []
        conf = np.flatnonzero(self.id > 0)
        if len(boxes) == 0 or len(conf) < 2:
            return mt, md, np.array(consumed, dtype=int)
        bi, pi = points_in_boxes(self.x[conf, :2], boxes)
        # A track whose centre lies in more than one detection box has a detection of its own.
        alone = np.bincount(pi, minlength=len(conf))[pi] == 1
        bi, pi = bi[alone], pi[alone]
        track_boxes = self.boxes()
        for d in np.flatnonzero(np.bincount(bi, minlength=len(boxes)) >= 2):
            tracks = conf[pi[bi == d]]
            taken = np.isin(mt, tracks) | (md == d)
            mt, md = mt[~taken], md[~taken]
            oldest = tracks[np.argmin(self.uid[tracks])]
            others = tracks[tracks != oldest]
            if np.all(_overlap_of_smaller(track_boxes[oldest], track_boxes[others]) > 0.5):
                mt, md = np.append(mt, oldest), np.append(md, d)
                self.misses[others] = self._KILLED
            else:
                consumed.append(int(d))
        return mt, md, np.array(consumed, dtype=int)

    def _update(self, mt: np.ndarray, boxes: np.ndarray, t: float, split: np.ndarray) -> None:
        """Update tracks `mt` with their detected boxes at time t (seed 001 eqs. 24-26);
        `split` marks those whose box held several vehicles (see _merge_fragments)."""
        cfg = self.cfg
        self._last_innov = np.zeros(len(mt))
        if len(mt) == 0:
            return
        centers, var = self._nested_centre(mt, boxes)
        for hist, newest in ((self.hist_s, np.sqrt(var)), (self.hist_p, centers), (self.hist_t, t)):
            hist[mt, 1:] = hist[mt, :-1]  # fancy indexing copies before the write
            hist[mt, 0] = newest
        self.count[mt] = np.minimum(self.count[mt] + 1, 3)
        z, R, mask = finite_difference_measurement(
            self.hist_p[mt], self.hist_t[mt], self.count[mt], self.hist_s[mt],
            position_only=cfg.measurement == "position")
        nu = z - self.x[mt]
        self._last_innov = np.hypot(nu[:, 0], nu[:, 1])
        if self.filters is None:
            H = np.tile(np.eye(6), (len(mt), 1, 1))
            self.x[mt], self.P[mt], _ = kf_update(self.x[mt], self.P[mt], nu, H, R, mask=mask)
        else:  # adaptive kinds adapt their own noise from the position innovations
            for i, zi in zip(mt, z[:, :2], strict=True):
                f = self.filters[int(self.uid[i])]
                f.update(zi)
                self.x[i], self.P[i] = f.x, f.P
        size = self.size[mt]
        grow = boxes[:, 2:] > size
        a = np.where(grow, cfg.size_smoothing, cfg.size_shrink)
        new = a * boxes[:, 2:] + (1 - a) * size
        # A blob that suddenly outgrows the vehicle is usually several vehicles merged: cap
        # the growth per frame (a vehicle coming into view at the border grows by about its
        # displacement per frame).
        dt = np.maximum(self.hist_t[mt, 0] - self.hist_t[mt, 1], 0.0)
        step = np.abs(self.x[mt, 2:4]) * np.where(self.count[mt] >= 2, dt, 0.0)[:, None]
        capped = np.minimum(new, size * (1 + cfg.max_size_growth) + step + 2.0)
        # A split track's other vehicles are not its size: it takes its piece's at once.
        self.size[mt] = np.where(split[:, None], boxes[:, 2:], capped)

    def _nested_centre(self, tracks: np.ndarray, boxes: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
        """A detected box as a measurement (z, var) of the centres of `tracks` (K, 2 each).

        A detection smaller than the vehicle (partly hidden by an occluder or the image
        border) or larger (merged with a shadow, a ghost or another vehicle) only says that
        the track's box and the detected box are nested. Per axis that puts the vehicle's
        centre in the interval between d0 + s/2 and d1 - s/2 (detection [d0, d1], track box
        size s), of length |w_det - s|; for a detection of the vehicle's size it is the
        detection's centre. z is the prediction clipped to that interval and its variance is
        the detector's sigma^2 plus that of a uniform spread over the interval, L^2 / 12.
        """
        half = self.size[tracks] / 2
        a = boxes[:, :2] + half
        b = boxes[:, :2] + boxes[:, 2:] - half
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        z = np.clip(self.x[tracks, :2], lo, hi)
        return z, self.cfg.detection_sigma**2 + (hi - lo) ** 2 / 12.0

    def _spawn(self, frame: int, t: float, centers: np.ndarray, boxes: np.ndarray,
               used: np.ndarray) -> int:
        """Start tentative tracks on unassigned detections that no confirmed track's box
        already covers (a fragment of a tracked vehicle is not a new vehicle)."""
        free = np.ones(len(centers), dtype=bool)
        free[used] = False
        conf = self.id > 0
        if conf.any() and free.any():
            idx = np.flatnonzero(free)
            _, covered = points_in_boxes(centers[idx], self.boxes()[conf])
            free[idx[covered]] = False
        new = np.flatnonzero(free)
        self._spawned_det = new
        k = len(new)
        if k == 0:
            return 0
        cfg = self.cfg
        x = np.zeros((k, 6))
        x[:, :2] = centers[new]
        P0 = np.diag([cfg.detection_sigma**2] * 2 + [cfg.init_speed_sigma**2] * 2
                     + [cfg.init_accel_sigma**2] * 2)
        hist_p = np.zeros((k, 3, 2))
        hist_p[:, 0] = centers[new]
        hist_t = np.zeros((k, 3))
        hist_t[:, 0] = t
        hist_s = np.full((k, 3, 2), cfg.detection_sigma)
        uid = np.arange(self.next_uid, self.next_uid + k)
        self.next_uid += k
        if self.filters is not None:
            for u, xi in zip(uid, x, strict=True):
                self.filters[int(u)] = make_filter(cfg.filter, self.model, self._position,
                                                   xi, P0)
        self._append(x=x, P=np.repeat(P0[None], k, axis=0), size=boxes[new, 2:].copy(),
                     origin=centers[new],
                     hist_p=hist_p, hist_t=hist_t, hist_s=hist_s, count=np.ones(k, dtype=int),
                     hitmask=np.ones(k, dtype=np.int64), misses=np.zeros(k, dtype=int),
                     id=np.zeros(k, dtype=int), uid=uid, gap_p=np.full((k, 2), np.nan),
                     gap_t=np.full(k, np.nan))
        return k

    def _fate(self) -> tuple[np.ndarray, np.ndarray]:
        """(inside, alive): whether part of each predicted box is still in the image, and
        whether the track is within its miss limit."""
        cfg = self.cfg
        m = cfg.edge_margin_px + self.size / 2
        inside = ((self.x[:, 0] >= -m[:, 0]) & (self.x[:, 0] <= self.width + m[:, 0])
                  & (self.x[:, 1] >= -m[:, 1]) & (self.x[:, 1] <= self.height + m[:, 1]))
        lost_for = self.t_prev - self.hist_t[:, 0]
        alive = np.where(self.id > 0, lost_for <= cfg.max_coast_seconds + 1e-9,
                         self.misses <= cfg.tentative_misses - 1)
        return inside, alive & (self.misses < self._KILLED)

    def _emit(self, frame: int, hit: np.ndarray, inside: np.ndarray, alive: np.ndarray
              ) -> np.ndarray:
        """The rows that became final this frame.

        Rows wait in `pending` until they are known to be part of a track: a tentative
        track's rows until it is confirmed (M-of-N hits and `confirm_motion`; they are then
        reported with its new id); a coasting track's predicted rows until a detection
        re-acquires it or its prediction leaves the image. A track deleted after
        `max_coast_seconds` without a detection never got its vehicle back, so its trailing
        predictions are dropped rather than reported.
        """
        cfg = self.cfg
        conf = np.where(hit, 1.0,
                        np.clip(1.0 - (self.t_prev - self.hist_t[:, 0])
                                / (cfg.max_coast_seconds + 1e-9), 0.05, 0.95))
        boxes = self.boxes()
        rows = np.column_stack([np.full(len(self), frame), self.id, boxes, conf])
        # A prediction at the image edge can clip to an empty box: such a row has no position
        # in the image and is not reported (INTERFACE: w, h > 0).
        visible = (boxes[:, 2] >= 1.0) & (boxes[:, 3] >= 1.0)
        waiting = np.fromiter(self.pending, dtype=int, count=len(self.pending))
        has_pending = np.isin(self.uid, waiting)
        simple = (self.id > 0) & hit & inside & alive & ~has_pending & visible
        out = [rows[simple]]
        hits = np.bitwise_count(self.hitmask)
        diagonal = np.hypot(self.size[:, 0], self.size[:, 1])
        moved = (np.hypot(*(self.hist_p[:, 0] - self.origin).T)
                 >= cfg.confirm_motion * diagonal)
        for i in np.flatnonzero(~simple):
            uid = int(self.uid[i])
            if not alive[i]:
                self.pending.pop(uid, None)
                continue
            if not inside[i]:
                if self.id[i] > 0:
                    out.extend(self.pending.pop(uid, []))
                else:
                    self.pending.pop(uid, None)
                continue
            if visible[i]:
                self.pending.setdefault(uid, deque(maxlen=self._MAX_PENDING)).append(rows[i])
            if self.id[i] == 0 and hits[i] >= cfg.confirm_hits and hit[i] and moved[i]:
                self.id[i] = self.next_id
                self.next_id += 1
            if self.id[i] > 0 and hit[i] and uid in self.pending:
                back = np.array(self.pending.pop(uid))
                back[:, 1] = self.id[i]
                out.append(back)
        return np.vstack(out) if out else np.zeros((0, 7))


def _overlap_of_smaller(box: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Intersection area of `box` with each of `others` over the smaller of the two areas."""
    x0 = np.maximum(box[0], others[:, 0])
    y0 = np.maximum(box[1], others[:, 1])
    x1 = np.minimum(box[0] + box[2], others[:, 0] + others[:, 2])
    y1 = np.minimum(box[1] + box[3], others[:, 1] + others[:, 3])
    inter = np.clip(x1 - x0, 0, None) * np.clip(y1 - y0, 0, None)
    smaller = np.minimum(box[2] * box[3], others[:, 2] * others[:, 3])
    return inter / np.maximum(smaller, 1e-9)


def points_in_boxes(points: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(box, point) index pairs with the point inside the box (x, y, w, h), among each box's 8
    nearest points (a box holds a few vehicle centres at most)."""
    centre = boxes[:, :2] + boxes[:, 2:] / 2
    radius = float(np.hypot(boxes[:, 2], boxes[:, 3]).max()) / 2 + 1e-9 if len(boxes) else 0.0
    bi, pi = nearest_pairs(centre, points, radius)
    inside = np.all(np.abs(points[pi] - centre[bi]) <= boxes[bi, 2:] / 2, axis=1)
    return bi[inside], pi[inside]
