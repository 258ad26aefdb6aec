"""Multi-target vehicle tracker: one constant-acceleration Kalman filter per vehicle, all
stepped together as arrays through the shared core.

The tracker is composed of roles, each in its own module:
- the track table (table.py): every track's state as parallel arrays;
- the filter bank (filter_bank.py): predict and update all tracks' filters;
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

from vtrack.tracking.associator import Association, Associator
from vtrack.tracking.config import ADAPTIVE_KINDS, TrackerConfig
from vtrack.tracking.filter_bank import FilterBank
from vtrack.tracking.lifecycle import Confirmer, Initiator, fate, record_hits
from vtrack.tracking.measurements import finite_difference_measurement, nested_centre
from vtrack.tracking.reporter import ROW_COLUMNS, RowReporter
from vtrack.tracking.table import TrackTable

__all__ = ["ADAPTIVE_KINDS", "ROW_COLUMNS", "FrameTracks", "Tracker", "TrackerConfig"]


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
        self.tracks = TrackTable.empty()
        self.bank = FilterBank(cfg)
        self.associator = Associator(cfg, width, height)
        self.initiator = Initiator(cfg)
        self.confirmer = Confirmer(cfg)
        self.reporter = RowReporter(cfg.max_coast_seconds)
        self.t_prev: float | None = None

    def __len__(self) -> int:
        return len(self.tracks)

    def step(self, frame: int, t: float, centers: np.ndarray, boxes: np.ndarray) -> FrameTracks:
        """Advance all tracks to time t (s) and assimilate this frame's detections."""
        centers = np.asarray(centers, dtype=float).reshape(-1, 2)
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        dt = 0.0 if self.t_prev is None else t - self.t_prev
        self.t_prev = t
        tracks = self.tracks
        self.bank.predict(tracks, dt)
        a = self.associator.associate(tracks, t, centers, boxes)
        tracks.killed[a.duplicates] = True
        innov = np.full(len(tracks), np.nan)
        innov[a.tracks] = self._update(a, t)
        hit = np.zeros(len(tracks), dtype=bool)
        hit[a.tracks] = True
        record_hits(tracks, hit, self.cfg.confirm_window)
        det_of = np.full(len(tracks), -1)
        det_of[a.tracks] = a.detections

        conf_boxes = tracks.boxes(self.width, self.height)[tracks.id > 0]
        new, started = self.initiator.start(t, a.centers, a.boxes,
                                            np.concatenate([a.detections, a.consumed]),
                                            conf_boxes)
        self.bank.start(new.uid, new.x, self.initiator.P0)
        tracks.append(new)
        innov = np.concatenate([innov, np.full(len(new), np.nan)])
        det_of = np.concatenate([det_of, started])
        hit = np.concatenate([hit, np.ones(len(new), dtype=bool)])

        inside, alive = fate(tracks, t, self.width, self.height, self.cfg)
        self.confirmer.confirm(tracks, hit, inside & alive)
        rows = self.reporter.rows(frame, t, tracks, tracks.boxes(self.width, self.height),
                                  hit, inside, alive)
        keep = inside & alive
        self.bank.forget(tracks.uid[~keep])
        tracks.keep(keep)
        hit, innov, det_of = hit[keep], innov[keep], det_of[keep]
        conf = tracks.id > 0
        return FrameTracks(ids=tracks.id[conf].copy(),
                           boxes=tracks.boxes(self.width, self.height)[conf],
                           coasted=~hit[conf], states=tracks.x[conf].copy(),
                           covariances=tracks.P[conf].copy(), innovations=innov[conf],
                           rows=rows, detection_of=det_of[conf],
                           size_rates=np.zeros((int(conf.sum()), 2)))

    def _update(self, a: Association, t: float) -> np.ndarray:
        """Update the tracks of association `a` with their detected boxes at time t (seed 001
        eqs. 24-26); returns their |position innovation| (px)."""
        cfg, tracks, mt = self.cfg, self.tracks, a.tracks
        if len(mt) == 0:
            return np.zeros(0)
        boxes = a.boxes[a.detections]
        centers, var = nested_centre(tracks.x[mt, :2], tracks.size[mt], boxes,
                                     cfg.detection_sigma)
        for hist, newest in ((tracks.hist_s, np.sqrt(var)), (tracks.hist_p, centers),
                             (tracks.hist_t, t)):
            hist[mt, 1:] = hist[mt, :-1]  # fancy indexing copies before the write
            hist[mt, 0] = newest
        tracks.count[mt] = np.minimum(tracks.count[mt] + 1, 3)
        z, R, mask = finite_difference_measurement(
            tracks.hist_p[mt], tracks.hist_t[mt], tracks.count[mt], tracks.hist_s[mt],
            position_only=cfg.measurement == "position")
        innov = self.bank.update(tracks, mt, z, R, mask)
        tracks.size[mt] = self._box_size(mt, boxes, a.split[mt])
        return innov

    def _box_size(self, mt: np.ndarray, boxes: np.ndarray, split: np.ndarray) -> np.ndarray:
        """The updated box sizes of tracks `mt` given their detected boxes: a larger
        detection weighs `size_smoothing`, a smaller `size_shrink` (it is often partly
        hidden); growth per frame is capped (a blob that suddenly outgrows the vehicle is
        usually several merged); a split track takes its piece's size at once."""
        cfg, tracks = self.cfg, self.tracks
        size = tracks.size[mt]
        grow = boxes[:, 2:] > size
        w = np.where(grow, cfg.size_smoothing, cfg.size_shrink)
        new = w * boxes[:, 2:] + (1 - w) * size
        # A vehicle coming into view at the border grows by about its displacement per frame.
        dt = np.maximum(tracks.hist_t[mt, 0] - tracks.hist_t[mt, 1], 0.0)
        step = np.abs(tracks.x[mt, 2:4]) * np.where(tracks.count[mt] >= 2, dt, 0.0)[:, None]
        capped = np.minimum(new, size * (1 + cfg.max_size_growth) + step + 2.0)
        return np.where(split[:, None], boxes[:, 2:], capped)
