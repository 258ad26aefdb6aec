"""Track lifecycle: initiation, confirmation and deletion.

tentative -> confirmed once detected in `confirm_fraction` of the frames of the last
`confirm_seconds` and moved `confirm_motion` box scales (static clutter never does) ->
coasting on the prediction while detections are lost (held in place, for up to
`max_stand_seconds`, when it was standing) -> deleted after `max_coast_seconds`
without a detection (a tentative track after `tentative_coast_seconds`), when its whole
predicted box has left the image, or as the duplicate of an older track.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from vtrack.boxes import clip, edges, from_centre, paired_iou
from vtrack.tracking.association import points_in_boxes
from vtrack.tracking.config import TrackerConfig
from vtrack.tracking.columns import Columns

if TYPE_CHECKING:
    from vtrack.tracking.table import TrackTable

MIN_INSIDE_SHARE = 0.25  # a coasted box keeps this share of its area in the image


@dataclass
class LifeColumns(Columns):
    """Per track: the lifecycle's record."""

    origin: np.ndarray     # (N, 4) the first detected box's edges x0, y0, x1, y1
    last_box: np.ndarray   # (N, 4) the last detected box's edges
    hitmask: np.ndarray    # (N,) bit i: detected i frames ago
    standing: np.ndarray   # (N,) a standing vehicle held without detections (record_hits)
    id: np.ndarray         # (N,) public id, 0 while tentative
    uid: np.ndarray        # (N,) internal id, unique for the run
    dup_t: np.ndarray      # (N,) since when it has shared an older track's detection (nan)
    seen: np.ndarray       # (N,) measured at least once by a box the appearance model drew

    LAYOUT: ClassVar[dict[str, tuple[tuple[int, ...], Any]]] = {
        "origin": ((4,), float), "last_box": ((4,), float), "hitmask": ((), np.int64),
        "standing": ((), bool), "id": ((), int), "uid": ((), int), "dup_t": ((), float),
        "seen": ((), bool)}

    def warp(self, m: np.ndarray) -> None:
        """Box corners map by m (the boxes stay axis-aligned)."""
        A, b = m[:, :2], m[:, 2]
        for e in (self.origin, self.last_box):
            e[:, :2] = e[:, :2] @ A.T + b
            e[:, 2:] = e[:, 2:] @ A.T + b


class Initiator:
    """Starts tentative tracks on detections no track explains."""

    def __init__(self, box_candidates: int) -> None:
        """`box_candidates`: TrackerConfig.box_candidates."""
        self.next_uid = 0
        self.box_candidates = box_candidates

    def select(self, centers: np.ndarray, used: np.ndarray, confirmed_boxes: np.ndarray,
               boxes: np.ndarray | None = None, whole: np.ndarray | None = None,
               same_iou: float = 0.5) -> np.ndarray:
        """The detections not `used` whose centre no confirmed track's box covers (a
        fragment of a tracked vehicle is not a new vehicle). A whole box (`whole`,
        provenance.py; `boxes` (D, 4) the detections' boxes) is a vehicle wherever its centre
        lies: it is left out only where it is a confirmed track's box (IoU >= `same_iou`)."""
        free = np.ones(len(centers), dtype=bool)
        free[used] = False
        if len(confirmed_boxes) and free.any():
            idx = np.flatnonzero(free)
            bi, covered = points_in_boxes(centers[idx], confirmed_boxes, self.box_candidates)
            if whole is not None and boxes is not None:
                k = idx[covered]
                # a blob in a box, or a whole box that is one of the boxes it lies in
                inner = ~whole[k] | (paired_iou(boxes[k], confirmed_boxes[bi]) >= same_iou)
                free[k[inner]] = False
            else:
                free[idx[covered]] = False
        return np.flatnonzero(free)

    def new(self, boxes: np.ndarray) -> LifeColumns:
        """The rows of tentative tracks first seen as `boxes` (x, y, w, h): no id yet, a
        new uid each."""
        k = len(boxes)
        origin = edges(boxes)
        uid = np.arange(self.next_uid, self.next_uid + k)
        self.next_uid += k
        return LifeColumns(origin, origin.copy(), np.zeros(k, dtype=np.int64),
                           np.zeros(k, dtype=bool), np.zeros(k, dtype=int), uid,
                           np.full(k, np.nan), np.zeros(k, dtype=bool))


def record_hits(tracks: TrackTable, hit: np.ndarray, window: int, stand_speed: float
                ) -> None:
    """Shift this frame's hits into each track's hit mask; a confirmed
    track without a detection whose speed plus its standard deviation is under stand_speed
    (box scales/s; a track whose speed is not yet known does not qualify) is standing: it
    is held where it stopped (velocity and acceleration set to 0) until a detection takes
    it up again."""
    tracks.hitmask = ((tracks.hitmask << 1) | hit) & ((1 << window) - 1)
    sd = np.sqrt(tracks.P[:, 2, 2] + tracks.P[:, 3, 3])
    slow = np.hypot(tracks.x[:, 2], tracks.x[:, 3]) + sd < stand_speed * tracks.scale
    stops = (tracks.id > 0) & ~hit & ~tracks.standing & slow
    tracks.x[stops, 2:] = 0.0
    tracks.standing = (tracks.standing | stops) & ~hit


class Deleter:
    """Decides which tracks end this frame: a track whose whole predicted box has left the
    image (`edge_margin` box scales beyond it), one past its coasting limit
    (`max_coast_seconds`; `max_stand_seconds` while standing; `tentative_coast_seconds`
    before confirmation) and the duplicates of older tracks (associator.py) once they have
    been duplicates on every frame for `duplicate_seconds`."""

    def __init__(self, cfg: TrackerConfig, width: int, height: int) -> None:
        self.cfg = cfg
        self.width, self.height = width, height

    def fate(self, tracks: TrackTable, t: float, duplicates: np.ndarray,
             patient: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(inside, alive) (N,) each: whether part of each predicted box is still in the
        image, and whether the track is within its coasting limit and not one of the
        `duplicates` (indices) for `duplicate_seconds` in a row (recorded in `dup_t`;
        `whole_duplicate_seconds` for those `patient` marks: they shared a whole box). A
        track is kept where both hold."""
        cfg = self.cfg
        m = cfg.edge_margin * tracks.scale[:, None] + tracks.size / 2
        x, y = tracks.x[:, 0], tracks.x[:, 1]
        inside = ((x >= -m[:, 0]) & (x <= self.width + m[:, 0])
                  & (y >= -m[:, 1]) & (y <= self.height + m[:, 1]))
        lost_for = t - tracks.hist_t[:, 0]
        inside &= ~((lost_for > 1e-9) & self._leaving(tracks))
        limit = np.where(tracks.id > 0, np.where(tracks.standing, cfg.max_stand_seconds,
                                                 cfg.max_coast_seconds),
                         cfg.tentative_coast_seconds)
        alive = lost_for <= limit + 1e-9
        shared = np.zeros(len(tracks), dtype=bool)
        shared[duplicates] = True
        wait = np.full(len(tracks), cfg.duplicate_seconds)
        if patient is not None:
            wait[duplicates[patient]] = cfg.whole_duplicate_seconds
        tracks.dup_t = np.where(shared, np.fmin(tracks.dup_t, t), np.nan)
        alive[shared & (t - tracks.dup_t >= wait - 1e-9)] = False
        return inside, alive

    def _leaving(self, tracks: TrackTable) -> np.ndarray:
        """(N,) tracks whose predicted box keeps under MIN_INSIDE_SHARE of its area in the
        image (its centre is then outside) and whose velocity points further out on an axis
        where the centre is outside: a vehicle driving out of the picture. Coasting, such a
        track has left: only its prediction says it is still there, and a vehicle that
        enters where it left would take it up."""
        predicted = from_centre(tracks.x[:, :2], tracks.size)
        share = (np.prod(clip(predicted, self.width, self.height)[:, 2:], axis=1)
                 / np.prod(tracks.size, axis=1))
        p, v = tracks.x[:, :2], tracks.x[:, 2:4]
        out = ((p < 0) & (v < 0)) | ((p > [self.width, self.height]) & (v > 0))
        return (share < MIN_INSIDE_SHARE) & out.any(axis=1)


class Confirmer:
    """M-of-N hits plus motion: hands out the public ids, in the order tracks confirm.

    The window is `confirm_seconds` long in frames of the video's rate (8 frames at 25 fps,
    18 at 60), M its `confirm_fraction`."""

    def __init__(self, cfg: TrackerConfig, fps: float) -> None:
        self.cfg = cfg
        self.window = int(np.clip(round(cfg.confirm_seconds * fps), 1, 62))
        self.hits = max(1, int(np.ceil(cfg.confirm_fraction * self.window - 1e-9)))
        self.next_id = 1

    def ready(self, tracks: TrackTable, hit: np.ndarray, eligible: np.ndarray) -> np.ndarray:
        """The tentative, `eligible` tracks detected this frame with M hits in their window
        that move: an edge of the detected box has moved `confirm_motion` box scales from
        where it was first seen (an edge, not the centre: a big vehicle coming into view at
        the image border grows there, its centre moves at half its speed; swaying leaves and
        flicker go nowhere), or the appearance model has seen them (a vehicle by its looks,
        standing or not: a queue from the first frame). Returns their indices."""
        cfg = self.cfg
        moved = (np.abs(tracks.last_box - tracks.origin).max(axis=1)
                 >= cfg.confirm_motion * tracks.scale) | tracks.seen
        return np.flatnonzero((tracks.id == 0) & eligible & hit & moved
                              & (np.bitwise_count(tracks.hitmask) >= self.hits))

    def confirm(self, tracks: TrackTable, idx: np.ndarray, ids: np.ndarray) -> None:
        """Confirm tracks idx with the ids they continue (reidentifier.py), a new id each
        where that is 0, handed out in order."""
        new = idx[ids == 0]
        tracks.id[idx] = ids
        tracks.id[new] = np.arange(self.next_id, self.next_id + len(new))
        self.next_id += len(new)
