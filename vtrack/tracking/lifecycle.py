"""Track lifecycle: initiation, confirmation and deletion.

tentative -> confirmed after `confirm_hits` hits in the last `confirm_window` frames, once it
has moved `confirm_motion` box diagonals (static clutter never does) -> coasting on the
prediction while detections are lost -> deleted after `max_coast_seconds` without a
detection (a tentative track after `tentative_misses` missed frames), when its whole
predicted box has left the image, or as the duplicate of an older track.
"""

from __future__ import annotations

import numpy as np

from vtrack.tracking.associator import points_in_boxes
from vtrack.tracking.config import TrackerConfig
from vtrack.tracking.table import TrackTable


class Initiator:
    """Starts tentative tracks on detections no track explains."""

    def __init__(self, cfg: TrackerConfig) -> None:
        self.cfg = cfg
        self.next_uid = 0
        s = cfg
        self.P0 = np.diag([s.detection_sigma**2] * 2 + [s.init_speed_sigma**2] * 2
                          + [s.init_accel_sigma**2] * 2)

    def start(self, t: float, centers: np.ndarray, boxes: np.ndarray, used: np.ndarray,
              confirmed_boxes: np.ndarray) -> tuple[TrackTable, np.ndarray]:
        """New tentative tracks on the detections not `used` whose centre no confirmed
        track's box covers (a fragment of a tracked vehicle is not a new vehicle).
        Returns the new tracks and the detections they started on."""
        free = np.ones(len(centers), dtype=bool)
        free[used] = False
        if len(confirmed_boxes) and free.any():
            idx = np.flatnonzero(free)
            _, covered = points_in_boxes(centers[idx], confirmed_boxes)
            free[idx[covered]] = False
        new = np.flatnonzero(free)
        k = len(new)
        table = TrackTable.empty()
        if k == 0:
            return table, new
        x = np.zeros((k, 6))
        x[:, :2] = centers[new]
        table.x, table.P = x, np.repeat(self.P0[None], k, axis=0)
        table.size, table.origin = boxes[new, 2:].copy(), centers[new]
        table.hist_p = np.zeros((k, 3, 2))
        table.hist_p[:, 0] = centers[new]
        table.hist_t = np.zeros((k, 3))
        table.hist_t[:, 0] = t
        table.hist_s = np.full((k, 3, 2), self.cfg.detection_sigma)
        table.count = np.ones(k, dtype=int)
        table.hitmask = np.ones(k, dtype=np.int64)
        table.misses = np.zeros(k, dtype=int)
        table.killed = np.zeros(k, dtype=bool)
        table.id = np.zeros(k, dtype=int)
        table.uid = np.arange(self.next_uid, self.next_uid + k)
        self.next_uid += k
        table.gap_p, table.gap_t = np.full((k, 2), np.nan), np.full(k, np.nan)
        return table, new


def record_hits(tracks: TrackTable, hit: np.ndarray, window: int) -> None:
    """Shift this frame's hits into each track's hit mask and count its misses."""
    tracks.hitmask = ((tracks.hitmask << 1) | hit) & ((1 << window) - 1)
    tracks.misses = np.where(hit, 0, tracks.misses + 1)


def fate(tracks: TrackTable, t: float, width: int, height: int, cfg: TrackerConfig
         ) -> tuple[np.ndarray, np.ndarray]:
    """(inside, alive): whether part of each predicted box is still in the image, and whether
    the track is within its miss limit (and not a duplicate)."""
    m = cfg.edge_margin_px + tracks.size / 2
    x, y = tracks.x[:, 0], tracks.x[:, 1]
    inside = ((x >= -m[:, 0]) & (x <= width + m[:, 0])
              & (y >= -m[:, 1]) & (y <= height + m[:, 1]))
    lost_for = t - tracks.hist_t[:, 0]
    alive = np.where(tracks.id > 0, lost_for <= cfg.max_coast_seconds + 1e-9,
                     tracks.misses <= cfg.tentative_misses - 1)
    return inside, alive & ~tracks.killed


class Confirmer:
    """M-of-N hits plus motion: hands out the public ids, in the order tracks confirm."""

    def __init__(self, cfg: TrackerConfig) -> None:
        self.cfg = cfg
        self.next_id = 1

    def confirm(self, tracks: TrackTable, hit: np.ndarray, eligible: np.ndarray) -> None:
        """Give an id to each tentative, `eligible` track detected this frame with
        `confirm_hits` hits in its window whose detected centre has moved `confirm_motion`
        box diagonals from where it was first seen."""
        cfg = self.cfg
        diagonal = np.hypot(tracks.size[:, 0], tracks.size[:, 1])
        moved = (np.hypot(*(tracks.hist_p[:, 0] - tracks.origin).T)
                 >= cfg.confirm_motion * diagonal)
        ready = ((tracks.id == 0) & eligible & hit & moved
                 & (np.bitwise_count(tracks.hitmask) >= cfg.confirm_hits))
        new = np.flatnonzero(ready)
        tracks.id[new] = np.arange(self.next_id, self.next_id + len(new))
        self.next_id += len(new)
