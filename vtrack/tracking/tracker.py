"""Multi-target vehicle tracker: one constant-acceleration Kalman filter per vehicle, all
stepped together as arrays through the shared core.

The tracker is composed of roles, each in its own module:
- the track table (table.py): every track's state as parallel arrays;
- the filter bank (filter_bank.py): predict and update all tracks' centre filters;
- the box size filter (box_size.py): every track's width and height with their rates;
- the associator (associator.py): fragments, gating and assignment, shared blobs,
  re-acquisition;
- the measurement (measurements.py): the nested-box centre and seed 001's finite
  differences;
- the lifecycle (lifecycle.py): initiator, confirmation, deleter;
- the reporter (reporter.py): which MOT rows are final.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from vtrack.boxes import clip, intersection, paired_iou
from vtrack.tracking.associator import Associator, ChangedShare, detection_sigma
from vtrack.tracking.fragments import GapColumns
from vtrack.tracking.box_size import BoxSizeFilter, anchored, own_size, remember_size
from vtrack.tracking.config import ADAPTIVE_KINDS, TrackerConfig
from vtrack.tracking.filter_bank import FilterBank
from vtrack.tracking.lifecycle import Confirmer, Deleter, Initiator, record_hits
from vtrack.tracking.measurements import (border_cut, box_centre, measurement_model,
                                          shrunk)
from vtrack.tracking.reporter import ON_COURSE_IOU, ROW_COLUMNS, RowReporter
from vtrack.tracking.scale_field import ScaleField
from vtrack.tracking.table import TrackTable

_IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

__all__ = ["ADAPTIVE_KINDS", "ROW_COLUMNS", "FrameTracks", "Tracker", "TrackerConfig"]


@dataclass
class FrameTracks:
    """The confirmed tracks after one frame (arrays over tracks) and the rows it emits."""

    ids: np.ndarray            # (K,) track ids
    boxes: np.ndarray          # (K, 4) x, y, w, h clipped to the image
    coasted: np.ndarray        # (K,) True when no detection updated the track this frame
    states: np.ndarray         # (K, 6) posterior [x, y, vx, vy, ax, ay]
    covariances: np.ndarray    # (K, 6, 6)
    innovations: np.ndarray    # (K,) NIS of this frame's update (nan when coasted)
    rows: np.ndarray           # (R, 7) ROW_COLUMNS to write (incl. rows back-filled later)
    detection_of: np.ndarray   # (K,) index of the detection used (-1 when coasted)
    size_rates: np.ndarray     # (K, 2) d(w, h)/dt of the box, px/s


class Tracker:
    """Array-based multi-target tracker. Per frame: `predict(t, motion)` (the predicted boxes,
    e.g. for the detector to split merged blobs), then `update(frame, t, centers, boxes)`;
    or `step`, which does both."""

    def __init__(self, cfg: TrackerConfig, width: int, height: int, fps: float = 25.0
                 ) -> None:
        cfg.validate()
        self.cfg = cfg
        self.width, self.height = width, height
        self.tracks = TrackTable.empty()
        self.gaps = GapColumns.empty()   # the associator's fragment stage's record
        self.bank = FilterBank(cfg)
        self.sizes = BoxSizeFilter(cfg.size_psd, cfg.size_sigma, cfg.size_rate_seconds,
                                   cfg.size_gate_probability,
                                   (cfg.size_grow_seconds, cfg.size_shrink_seconds))
        self.field = ScaleField(width, height)
        self.associator = Associator(cfg, width, height)
        self.initiator = Initiator(cfg.box_candidates)
        self.confirmer = Confirmer(cfg, fps)
        self.deleter = Deleter(cfg, width, height)
        self.reporter = RowReporter(cfg.max_coast_seconds, width, height,
                                    self.bank.model.transition if cfg.smooth_coasted else None)
        self.t_prev: float | None = None

    def __len__(self) -> int:
        return len(self.tracks)

    @property
    def max_row_lag(self) -> int:
        """Rows come out of `update` late (a tentative track's once it is confirmed, coasted
        ones once the vehicle is re-acquired), but never this many frames late: after frame
        g, no row of a frame <= g - max_row_lag will come."""
        return self.reporter.MAX_PENDING + 1

    def step(self, frame: int, t: float, centers: np.ndarray, boxes: np.ndarray,
             motion: np.ndarray | None = None, changed: ChangedShare | None = None
             ) -> FrameTracks:
        """predict, then update (see those)."""
        self.predict(t, motion)
        return self.update(frame, t, centers, boxes, changed)

    def predict(self, t: float, motion: np.ndarray | None = None) -> np.ndarray:
        """Advance all tracks to time t (s); `motion` (2, 3) is the camera's, mapping the
        previous frame's pixels onto this frame's. Returns the confirmed tracks' predicted
        boxes (K, 4), x, y, w, h (not clipped to the image)."""
        dt = 0.0 if self.t_prev is None else t - self.t_prev
        self.t_prev = t
        tracks = self.tracks
        if motion is not None and len(tracks) and not np.allclose(motion, _IDENTITY):
            tracks.warp(motion)
            self.gaps.warp(motion)
        growth = (self.field.log_rate(tracks.x[:, :2], tracks.x[:, 2:4])
                  if self.cfg.scale_field else np.zeros(len(tracks)))
        self.bank.predict(tracks, dt)
        tracks.s, tracks.Ps = self.sizes.predict(tracks.s, tracks.Ps, dt, growth)
        conf = tracks.id > 0
        size = tracks.size[conf]
        return np.hstack([tracks.x[conf, :2] - size / 2, size])

    def update(self, frame: int, t: float, centers: np.ndarray, boxes: np.ndarray,
               changed: ChangedShare | None = None) -> FrameTracks:
        """Assimilate frame `frame`'s detections (centres (D, 2), boxes (D, 4)) into the
        tracks predicted to its time t. `changed`, when the detector has one, gives the share
        of any box (K, 4) that it saw change (vision/changed.py): the associator reads the
        gap between two pieces of a blob with it."""
        centers = np.asarray(centers, dtype=float).reshape(-1, 2)
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        tracks = self.tracks
        a = self.associator.associate(tracks, self.gaps, t, centers, boxes,
                                      changed if self.cfg.gap_labels else None)
        self.gaps = a.gaps
        innov = np.full(len(tracks), np.nan)
        predicted = tracks.boxes(self.width, self.height)[a.tracks]
        prior_x, prior_P = tracks.x.copy(), tracks.P.copy()
        innov[a.tracks], whole = self._update(a.tracks, a.boxes[a.detections], t,
                                              a.split[a.tracks])
        hit = np.zeros(len(tracks), dtype=bool)
        hit[a.tracks] = True
        det_of = np.full(len(tracks), -1)
        det_of[a.tracks] = a.detections

        conf_boxes = tracks.boxes(self.width, self.height)[tracks.id > 0]
        started = self.initiator.select(a.centers, np.concatenate([a.detections, a.consumed]),
                                        conf_boxes)
        n_old = len(tracks)
        self._start(t, a.centers[started], a.boxes[started])
        new = np.arange(n_old, len(tracks))
        innov = np.concatenate([innov, self._update(new, a.boxes[started], t,
                                                    np.zeros(len(new), dtype=bool))[0]])
        det_of = np.concatenate([det_of, started])
        hit = np.concatenate([hit, np.ones(len(new), dtype=bool)])
        record_hits(tracks, hit, self.confirmer.window, self.cfg.stand_speed)

        inside, alive = self.deleter.fate(tracks, t, a.duplicates)
        self.confirmer.confirm(tracks, hit, inside & alive)
        # A detected row shows the detection's box where it showed the whole vehicle (the
        # filtered box lags a vehicle's change of size); a re-acquired track's coasted rows
        # are reported only if the detection confirms where the prediction put it.
        filtered = tracks.boxes(self.width, self.height)
        shown = filtered.copy()
        shown[a.tracks[whole]] = clip(a.boxes[a.detections][whole], self.width, self.height)
        on_course = np.ones(len(tracks), dtype=bool)
        on_course[a.tracks] = paired_iou(predicted, shown[a.tracks]) >= ON_COURSE_IOU
        rows = self.reporter.rows(frame, t, tracks, shown, hit, on_course, inside, alive,
                                  prior_x, prior_P)
        keep = inside & alive
        self.bank.forget(tracks.uid[~keep])
        tracks.keep(keep)
        self.gaps.keep(keep)
        hit, innov, det_of = hit[keep], innov[keep], det_of[keep]
        conf = tracks.id > 0
        return FrameTracks(ids=tracks.id[conf].copy(), boxes=filtered[keep][conf],
                           coasted=~hit[conf], states=tracks.x[conf].copy(),
                           covariances=tracks.P[conf].copy(), innovations=innov[conf],
                           rows=rows, detection_of=det_of[conf],
                           size_rates=self._size_rates(conf))

    def _size_rates(self, idx: np.ndarray) -> np.ndarray:
        """d(w, h)/dt (px/s) of tracks idx: the growth the scene's perspective gives their
        motion plus the size filter's own rates."""
        tracks = self.tracks
        growth = (self.field.log_rate(tracks.x[idx, :2], tracks.x[idx, 2:4])
                  if self.cfg.scale_field else np.zeros(len(tracks.x[idx])))
        return tracks.size[idx] * (growth[:, None] + tracks.s[idx, 2:])

    def _start(self, t: float, centers: np.ndarray, boxes: np.ndarray) -> None:
        """Append tentative tracks on these detections (assimilated by _update next)."""
        scale = np.sqrt(boxes[:, 2] * boxes[:, 3])
        var = np.repeat(detection_sigma(self.cfg, scale)[:, None] ** 2, 2, axis=1)
        x0, P0 = self.bank.prior(centers, scale)
        s0, Ps0 = self.sizes.initial(boxes[:, 2:], self.cfg.init_size_rate_sigma)
        new = self.initiator.table(t, boxes, x0, P0, s0, Ps0)
        self.bank.start(new.uid, x0, var, scale)
        self.tracks.append(new)
        self.gaps.append(GapColumns.new(len(boxes)))

    def _learn_scale(self, idx: np.ndarray, boxes: np.ndarray) -> None:
        """Feed the scale field with whole-vehicle boxes of confirmed tracks whose box
        overlaps no other track's: a pair once the track has moved half a box scale."""
        tracks = self.tracks
        conf = tracks.id[idx] > 0
        idx, boxes = idx[conf], boxes[conf]
        if len(idx) == 0:
            return
        all_boxes = tracks.boxes(self.width, self.height)
        centre = all_boxes[:, :2] + all_boxes[:, 2:] / 2
        # Boxes that overlap have centres within the largest diagonal (k-d tree pairs).
        near = cKDTree(centre).query_ball_point(
            centre[idx], float(np.hypot(all_boxes[:, 2], all_boxes[:, 3]).max()))
        qi = np.repeat(np.arange(len(idx)), [len(n) for n in near])
        pj = np.fromiter((j for n in near for j in n), dtype=int, count=len(qi))
        other = pj != idx[qi]
        qi, pj = qi[other], pj[other]
        touching = qi[intersection(all_boxes[idx[qi]], all_boxes[pj]) > 0]
        alone = np.bincount(touching, minlength=len(idx)) == 0
        idx, boxes = idx[alone], boxes[alone]
        p = boxes[:, :2] + boxes[:, 2:] / 2
        sc = np.sqrt(boxes[:, 2] * boxes[:, 3])
        ref = tracks.ref_s[idx]
        far = np.hypot(*(p - tracks.ref_p[idx]).T) >= 0.5 * np.fmin(sc, ref)
        pair = np.isfinite(ref) & far
        self.field.add(tracks.ref_p[idx[pair]], ref[pair], p[pair], sc[pair])
        new = ~np.isfinite(ref) | pair
        tracks.ref_p[idx[new]], tracks.ref_s[idx[new]] = p[new], sc[new]

    def _update(self, mt: np.ndarray, boxes: np.ndarray, t: float, split: np.ndarray
                ) -> np.ndarray:
        """Update tracks `mt` with their detected boxes at time t: the box size where the
        detection shows the whole vehicle (box_size.py; a split track's size starts again
        from its piece), the centre from the nested boxes (seed 001 eqs. 24-26). Returns
        the NIS and whether each detection showed the whole vehicle (no side partial or
        cut by the image border, not a piece of a split blob)."""
        cfg, tracks = self.cfg, self.tracks
        if len(mt) == 0:
            return np.zeros(0), np.zeros(0, dtype=bool)
        size, pos_var = tracks.size[mt], tracks.P[mt][:, [0, 1], [0, 1]]
        size_var = self.sizes.px_var(tracks.s[mt], tracks.Ps[mt])
        edges_cut = border_cut(boxes, self.width, self.height)
        cut = edges_cut.any(axis=2)
        expected = spread = np.full((len(mt), 2), np.nan)
        rates = self._size_rates(mt)
        partial = anchored(tracks, mt, boxes, t, rates)
        if cfg.own_size:
            expected, spread = own_size(tracks.own[mt], self.field.k(tracks.x[mt, :2]))
            expected[partial] = np.nan
            remember_size(tracks, mt, boxes, self.field.k(boxes[:, :2] + boxes[:, 2:] / 2),
                          cut.any(axis=1) | partial)
        # A vehicle receding (its box shrinking: the scene's perspective and the size
        # filter's rates) faster than its size estimate follows: the size starts again
        # from the detection.
        sigma = detection_sigma(cfg, np.sqrt(size.prod(axis=1)))[:, None]
        receding = np.all(rates < 0, axis=1)
        smaller = ((shrunk(tracks.x[mt, :2], size, boxes, sigma) & receding & ~partial)[:, None]
                   & ~cut)
        # A whole side is never a border-cut one (box_size.py), so `shows_whole` has no cut.
        whole = self.sizes.update(tracks, mt, boxes[:, 2:], cut, t, expected, spread, smaller)
        shows_whole = whole.all(axis=1) & ~split
        self._learn_scale(mt[shows_whole], boxes[shows_whole])
        if split.any():
            k = mt[split]
            s_new, Ps_new = self.sizes.initial(boxes[split, 2:], cfg.init_size_rate_sigma)
            s_new[:, 2:], Ps_new[:, 2:, 2:] = tracks.s[k, 2:], tracks.Ps[k][:, 2:, 2:]
            tracks.s[k], tracks.Ps[k] = s_new, Ps_new
        centers, var = box_centre(tracks.x[mt, :2], pos_var, size, size_var, boxes, whole,
                                  sigma, edges_cut)
        for hist, newest in ((tracks.hist_s, np.sqrt(var)), (tracks.hist_p, centers),
                             (tracks.hist_t, t)):
            hist[mt, 1:] = hist[mt, :-1]  # fancy indexing copies before the write
            hist[mt, 0] = newest
        tracks.count[mt] = np.minimum(tracks.count[mt] + 1, 3)
        tracks.last_box[mt] = np.hstack([boxes[:, :2], boxes[:, :2] + boxes[:, 2:]])
        z, Hm, R, mask = measurement_model(tracks.hist_p[mt], tracks.hist_t[mt],
                                           tracks.count[mt], tracks.hist_s[mt], cfg.measurement)
        return self.bank.update(tracks, mt, z, Hm, R, mask), shows_whole
