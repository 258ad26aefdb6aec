"""Multi-target vehicle tracker: one constant-acceleration Kalman filter per vehicle, all
stepped together as arrays through the shared core.

`Tracker.update` is one page of role calls, in this order: associate, update sizes, measure
centres, update centres, initiate (and assimilate the new tracks alike), record hits,
decide deletions, confirm, report, delete. Each role is in its own module and owns its
per-track columns (their initial values and their warp under camera motion); the track
table (table.py) joins them:
- the filter bank (filter_bank.py; CentreColumns x, P): predicts and updates all tracks'
  centre filters;
- the size role (sizes.py; SizeColumns s, Ps, mismatch_t, mismatch_sign, own, ref_p,
  ref_s): every track's width and height with their rates (box_size.py) and the scene's
  scale field (scale_field.py), behind one `update`;
- the centre measurement (measurements.py; HistoryColumns hist_p, hist_t, hist_s, count):
  the nested-box centre and seed 001's finite differences;
- the associator (associator.py): fragments (fragments.py; GapColumns gap_p, gap_t,
  gap_seen, gap_road, kept apart by the tracker), gating and assignment, shared blobs,
  re-acquisition; it changes nothing and returns its decisions;
- the lifecycle (lifecycle.py; LifeColumns origin, last_box, hitmask, standing, id, uid,
  dup_t, seen): initiator, confirmer, deleter;
- the re-identifier (reidentifier.py; ReidColumns born, v_seen, colour): remembers the
  vehicles lost in view and hands their ids to the tracks that continue them;
- the reporter (reporter.py): which MOT rows are final, a state machine.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vtrack.boxes import clip, from_centre, paired_iou
from vtrack.boxes import scale as box_scale
from vtrack.tracking.associator import Associator, ChangedShare
from vtrack.tracking.config import ADAPTIVE_KINDS, TrackerConfig
from vtrack.tracking.filter_bank import FilterBank
from vtrack.tracking.fragments import GapColumns
from vtrack.tracking.lifecycle import Confirmer, Deleter, Initiator, record_hits
from vtrack.tracking.measurements import CentreMeasurement, HistoryColumns, detection_sigma
from vtrack.tracking.provenance import whole_boxes
from vtrack.tracking.reidentifier import ReidColumns, Reidentifier
from vtrack.tracking.reporter import ON_COURSE_IOU, ROW_COLUMNS, RowReporter
from vtrack.tracking.sizes import Sizes
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
    detection_of: np.ndarray   # (K,) index of the input detection used (-1 when coasted;
                               # a joined blob: its first piece)
    size_rates: np.ndarray     # (K, 2) d(w, h)/dt of the box, px/s
    held: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
                               # (M,) ids of vehicles lost in view that may come back
                               # (reidentifier.py): their records stay open


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
        self.sizes = Sizes(cfg, width, height)
        self.centres = CentreMeasurement(cfg)
        self.associator = Associator(cfg, width, height)
        self.initiator = Initiator(cfg.box_candidates)
        self.confirmer = Confirmer(cfg, fps)
        self.reidentifier = Reidentifier(cfg, width, height)
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
             motion: np.ndarray | None = None, changed: ChangedShare | None = None,
             seen: np.ndarray | None = None, colours: np.ndarray | None = None
             ) -> FrameTracks:
        """predict, then update (see those)."""
        self.predict(t, motion)
        return self.update(frame, t, centers, boxes, changed, seen, colours)

    def predict(self, t: float, motion: np.ndarray | None = None) -> np.ndarray:
        """Advance all tracks to time t (s); `motion` (2, 3) is the camera's, mapping the
        previous frame's pixels onto this frame's. Returns the confirmed tracks' predicted
        boxes (K, 4), x, y, w, h (not clipped to the image)."""
        dt = 0.0 if self.t_prev is None else t - self.t_prev
        tracks = self.tracks
        # coasting: no detection at the last step's time (the newest one is older); only
        # Singer's coasting model (coast_accel_rate) reads it
        coasting = (tracks.hist_t[:, 0] < t - dt - 1e-9
                    if self.cfg.coast_accel_rate > 0 else None)
        self.t_prev = t
        if motion is not None and len(tracks) and not np.allclose(motion, _IDENTITY):
            tracks.warp(motion)
            self.gaps.warp(motion)
            self.reidentifier.lost.warp(motion)
        growth = self.sizes.growth(tracks)   # from the velocities and scales before the step
        self.bank.predict(tracks, dt, coasting)
        self.sizes.predict(tracks, dt, growth)
        conf = tracks.id > 0
        return from_centre(tracks.x[conf, :2], tracks.size[conf])

    def update(self, frame: int, t: float, centers: np.ndarray, boxes: np.ndarray,
               changed: ChangedShare | None = None, seen: np.ndarray | None = None,
               colours: np.ndarray | None = None) -> FrameTracks:
        """Assimilate frame `frame`'s detections (centres (D, 2), boxes (D, 4)) into the
        tracks predicted to its time t. `changed`, when the detector has one, gives the share
        of any box (K, 4) that it saw change (vision/changed.py): the associator reads the
        gap between two pieces of a blob with it. `seen` (D,) marks the boxes an appearance
        model drew: whole vehicles, which every role treats as whole (provenance.py).
        `colours` (D, reidentifier.SIGNATURE_SIZE), the boxes' colour signatures
        (vision/colour.py), let a vehicle lost for seconds come back with its id."""
        centers = np.asarray(centers, dtype=float).reshape(-1, 2)
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        whole_in = whole_boxes(seen, len(boxes))
        tracks, W, H = self.tracks, self.width, self.height
        # associate: which detection updates which track (decisions only)
        a = self.associator.associate(tracks, self.gaps, t, centers, boxes,
                                      changed if self.cfg.gap_labels else None,
                                      whole_in if whole_in.any() else None)
        self.gaps = a.gaps
        predicted = a.track_boxes[a.tracks]
        prior_x, prior_P = tracks.x.copy(), tracks.P.copy()
        # update sizes, measure centres, update centres (the tracks detected)
        innov, whole = self._assimilate(a.tracks, a.boxes[a.detections], t, a.split[a.tracks],
                                        a.whole[a.detections])
        # initiate: tentative tracks on the detections no track explains, assimilated alike
        started = self.initiator.select(a.centers, np.concatenate([a.detections, a.consumed]),
                                        tracks.boxes(W, H)[tracks.id > 0], a.boxes, a.whole,
                                        self.cfg.blob_fit_iou)
        new = self._start(t, a.centers[started], a.boxes[started])
        innov_new, _ = self._assimilate(new, a.boxes[started], t, np.zeros(len(new), bool),
                                        a.whole[started])
        hit = np.zeros(len(tracks), dtype=bool)
        hit[a.tracks] = hit[new] = True
        for idx, det in ((a.tracks, a.origin[a.detections]), (new, a.origin[started])):
            self.reidentifier.observe(tracks, idx, None if colours is None else colours[det])
        tracks.seen[a.tracks[a.whole[a.detections]]] = True
        tracks.seen[new[a.whole[started]]] = True
        record_hits(tracks, hit, self.confirmer.window, self.cfg.stand_speed)
        # delete (decide), confirm: a new id, or the id of the lost vehicle it continues
        inside, alive = self.deleter.fate(tracks, t, a.duplicates, a.patient)
        ready = self.confirmer.ready(tracks, hit, inside & alive)
        self.confirmer.confirm(tracks, ready, self.reidentifier.claim(tracks, ready, t))
        # report
        filtered = tracks.boxes(W, H)
        shown, on_course = self._shown(filtered, predicted, a.tracks,
                                       a.boxes[a.detections], whole)
        rows = self.reporter.rows(frame, t, tracks, shown, hit, on_course, inside, alive,
                                  prior_x, prior_P)
        # delete (apply), remembering the vehicles lost in view
        keep = inside & alive
        self.reidentifier.remember(tracks, ~keep, inside, t)
        self._delete(~keep)
        det_of = np.full(len(keep), -1)
        det_of[a.tracks], det_of[new] = a.origin[a.detections], a.origin[started]
        nis = np.full(len(keep), np.nan)
        nis[a.tracks], nis[new] = innov, innov_new
        return self._frame_tracks(rows, filtered[keep], hit[keep], nis[keep], det_of[keep])

    def _shown(self, filtered: np.ndarray, predicted: np.ndarray, idx: np.ndarray,
               boxes: np.ndarray, whole: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The box each track's row shows, and whether each detected track is on course.
        A detected row shows the detection's box (clipped) where it showed the whole
        vehicle (the filtered box lags a vehicle's change of size), else the filtered box;
        tracks idx detected as `boxes` are on course where their predicted box and the shown
        one overlap with IoU >= ON_COURSE_IOU (a re-acquired track's coasted rows are
        reported only then, reporter.py)."""
        shown = filtered.copy()
        shown[idx[whole]] = clip(boxes[whole], self.width, self.height)
        on_course = np.ones(len(filtered), dtype=bool)
        on_course[idx] = paired_iou(predicted, shown[idx]) >= ON_COURSE_IOU
        return shown, on_course

    def _frame_tracks(self, rows: np.ndarray, boxes: np.ndarray, hit: np.ndarray,
                      nis: np.ndarray, det_of: np.ndarray) -> FrameTracks:
        """The confirmed tracks after the frame (boxes, hit, nis, det_of over the kept
        tracks)."""
        tracks = self.tracks
        conf = tracks.id > 0
        return FrameTracks(ids=tracks.id[conf].copy(), boxes=boxes[conf], coasted=~hit[conf],
                           states=tracks.x[conf].copy(), covariances=tracks.P[conf].copy(),
                           innovations=nis[conf], rows=rows, detection_of=det_of[conf],
                           size_rates=self.sizes.rates(tracks, conf),
                           held=self.reidentifier.held)

    def _assimilate(self, idx: np.ndarray, boxes: np.ndarray, t: float, split: np.ndarray,
                    whole_box: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Update tracks idx with their detected boxes (K, 4) at time t: the size role first
        (sizes.py; split (K,) marks tracks whose box held several vehicles, whole_box (K,)
        the boxes the appearance model drew), then the centre measured from what it decided
        the box showed (measurements.py, seed 001 eqs. 24-26) and the centre filters'
        update. Returns the NIS (K,) and whether each detection showed the whole vehicle."""
        if len(idx) == 0:
            return np.zeros(0), np.zeros(0, dtype=bool)
        sizes = self.sizes.update(self.tracks, idx, boxes, t, split, whole_box)
        z, Hm, R, mask = self.centres.measure(self.tracks, idx, boxes, t, sizes)
        return self.bank.update(self.tracks, idx, z, Hm, R, mask), sizes.shows_whole

    def _start(self, t: float, centers: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """Append tentative tracks on these detections (assimilated by _assimilate next);
        returns their indices."""
        if len(boxes) == 0:
            return np.zeros(0, dtype=int)
        scale = box_scale(boxes)
        var = np.repeat(detection_sigma(self.cfg, scale)[:, None] ** 2, 2, axis=1)
        new = TrackTable(centre=self.bank.prior(centers, scale),
                         history=HistoryColumns.new(len(boxes), t),
                         box_size=self.sizes.new(boxes), life=self.initiator.new(boxes),
                         reid=ReidColumns.new(len(boxes), t))
        self.bank.start(new.uid, new.x, var, scale)
        n_old = len(self.tracks)
        self.tracks.append(new)
        self.gaps.append(GapColumns.new(len(boxes)))
        return np.arange(n_old, len(self.tracks))

    def _delete(self, ended: np.ndarray) -> None:
        """Remove the tracks `ended` (N,) from every role that holds per-track state."""
        if not ended.any():
            return
        self.bank.forget(self.tracks.uid[ended])
        self.tracks.keep(~ended)
        self.gaps.keep(~ended)
