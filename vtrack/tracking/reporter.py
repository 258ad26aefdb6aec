"""Which MOT rows are final: a track's rows are reported once they are known to belong to a
vehicle.

Rows wait until then: a tentative track's rows until it is confirmed (they are reported with
its new id, so its start is not lost); a coasting track's predicted rows until a detection
re-acquires it or its prediction leaves the image. A coasted stretch is reported only if the
detection that ends it confirms the prediction -- the predicted box and the updated box
overlap with IoU >= `ON_COURSE_IOU`, the MOT matching criterion: where they do not, the
prediction had drifted off the vehicle (or onto another) and its rows would be false
positives. A stretch that ends with the prediction leaving the image has no detection to
confirm or refute it; it is reported when the track leaves on its vehicle's way (its
velocity along its net displacement since its first detection: a vehicle lost before a
counting line and coasting over it still counts; dropping every such stretch cost a count
on a real clip), and dropped when it veered off it (the last boxes of a merged or piecewise
blob jumped, and the prediction follows the jump, not a vehicle). A track
deleted after `max_coast_seconds` without a detection never got its vehicle back, so its
trailing predictions are dropped. A coasted row whose box keeps under `MIN_INSIDE_SHARE` of
its area in the image is not reported at all: that sliver at the border is placed by the
prediction alone (on the scene suite none of the 70 such rows scored matched a
vehicle).

A coasted stretch that a detection confirms is reported smoothed: the fixed-interval (RTS)
smoother carries the re-acquisition's correction back over the predictions
(kalman.smooth_gap), so the rows follow a vehicle that braked or sped up while unseen
instead of the straight prediction. Rows of a standing track (held in place on purpose, not
predicted) and rows whose box the image border cuts (their centre is not the box's) keep
their predicted boxes.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from vtrack.estimation.kalman import smooth_gap
from vtrack.tracking.table import TrackTable

ROW_COLUMNS = ("frame", "id", "x", "y", "w", "h", "conf")  # conf 1 = detected, < 1 = coasted
ON_COURSE_IOU = 0.5  # a re-acquisition this close to the prediction confirms the coasted rows
MIN_INSIDE_SHARE = 0.25  # a coasted row keeps this share of its predicted box in the image


class CoastedRow(NamedTuple):
    """A coasted row's predicted centre state, kept for smoothing once it is confirmed."""

    frame: int
    t: float
    x: np.ndarray     # (6,) predicted [x, y, vx, vy, ax, ay]
    P: np.ndarray     # (6, 6)
    size: np.ndarray  # (2,) predicted box width and height


class RowReporter:
    """Holds the rows not yet final, by track uid."""

    MAX_PENDING = 4096  # rows kept for a track not yet confirmed (static clutter is bounded)

    def __init__(self, max_coast_seconds: float, width: int, height: int,
                 transition: Callable[[float], np.ndarray] | None = None) -> None:
        """`transition(dt)`: the centre filters' state transition, which smooths coasted
        stretches (None: they are reported as predicted)."""
        self.max_coast = max_coast_seconds
        self.width, self.height = width, height
        self.transition = transition
        self.pending: dict[int, deque[np.ndarray]] = {}
        self.coasted: dict[int, list[CoastedRow]] = {}  # by uid, since its last detection

    def rows(self, frame: int, t: float, tracks: TrackTable, boxes: np.ndarray,
             hit: np.ndarray, on_course: np.ndarray, inside: np.ndarray, alive: np.ndarray,
             prior_x: np.ndarray, prior_P: np.ndarray) -> np.ndarray:
        """The rows (R, 7) of ROW_COLUMNS that became final this frame; `boxes` are the
        tracks' boxes clipped to the image; on_course marks the hit tracks whose detection
        confirms their prediction; (prior_x, prior_P) are the centre states before this
        frame's update of the tracks that existed before it (tracks born this frame come
        after them and have no coasted rows). conf is 1 for a detected row and falls from 0.95 to
        0.05 over the coasting limit."""
        conf = np.where(hit, 1.0,
                        np.clip(1.0 - (t - tracks.hist_t[:, 0]) / (self.max_coast + 1e-9),
                                0.05, 0.95))
        rows = np.column_stack([np.full(len(tracks), frame), tracks.id, boxes, conf])
        # A prediction at the image edge can clip to an empty box: such a row has no position
        # in the image and is not reported (INTERFACE: w, h > 0). Nor is a coasted row whose
        # clipped box keeps under MIN_INSIDE_SHARE of its predicted box: a sliver at the
        # border placed by the prediction alone, not by a detection.
        inside_share = boxes[:, 2] * boxes[:, 3] / np.prod(tracks.size, axis=1)
        visible = ((boxes[:, 2] >= 1.0) & (boxes[:, 3] >= 1.0)
                   & (hit | (inside_share >= MIN_INSIDE_SHARE)))
        waiting = np.fromiter(self.pending, dtype=int, count=len(self.pending))
        has_pending = np.isin(tracks.uid, waiting)
        confirmed = tracks.id > 0
        simple = confirmed & hit & inside & alive & ~has_pending & visible
        out = [rows[simple]]
        for i in np.flatnonzero(~simple):
            uid = int(tracks.uid[i])
            if not alive[i]:
                self.pending.pop(uid, None)
                self.coasted.pop(uid, None)
                continue
            if not inside[i]:
                self.coasted.pop(uid, None)
                tail = self.pending.pop(uid, [])
                if confirmed[i] and leaves_on_its_way(tracks, i):
                    out.extend(tail)
                continue
            if hit[i] and not on_course[i] and uid in self.pending:
                drop_coasted_tail(self.pending[uid])
            elif hit[i] and uid in self.coasted and uid in self.pending:
                self._smooth(self.pending[uid], self.coasted[uid], t, tracks.x[i],
                             prior_x[i], prior_P[i])
            if hit[i]:
                self.coasted.pop(uid, None)
            if visible[i]:
                self.pending.setdefault(uid, deque(maxlen=self.MAX_PENDING)).append(rows[i])
                if tracks.standing[i]:     # held on purpose, not predicted: not smoothed
                    self.coasted.pop(uid, None)
                elif self.transition is not None and not hit[i]:
                    self.coasted.setdefault(uid, []).append(CoastedRow(
                        frame, t, tracks.x[i].copy(), tracks.P[i].copy(),
                        tracks.size[i].copy()))
            if confirmed[i] and hit[i] and uid in self.pending:
                back = np.array(self.pending.pop(uid))
                back[:, 1] = tracks.id[i]
                out.append(back)
        return np.vstack(out) if out else np.zeros((0, 7))

    def _smooth(self, rows: deque[np.ndarray], stretch: list[CoastedRow], t: float,
                x_post: np.ndarray, x_prior: np.ndarray, P_prior: np.ndarray) -> None:
        """Move the coasted rows of `stretch` (in `rows`) onto their smoothed centres, in
        place, where the predicted and the smoothed box both lie inside the image."""
        x = smooth_gap(np.array([c.x for c in stretch]), np.array([c.P for c in stretch]),
                       np.array([self.transition(t - c.t) for c in stretch]),
                       x_prior, P_prior, x_post)
        moved = {}
        for c, xs in zip(stretch, x, strict=True):
            before = np.concatenate([c.x[:2] - c.size / 2, c.size])
            after = np.concatenate([xs[:2] - c.size / 2, c.size])
            if self._in_image(before) and self._in_image(after):
                moved[c.frame] = after
        for r in rows:
            if r[6] < 1.0 and int(r[0]) in moved:
                r[2:6] = moved[int(r[0])]

    def _in_image(self, box: np.ndarray) -> bool:
        return bool(box[0] >= 0 and box[1] >= 0 and box[0] + box[2] <= self.width
                    and box[1] + box[3] <= self.height)


def leaves_on_its_way(tracks: TrackTable, i: int) -> bool:
    """Whether track i coasted out of the image the way its vehicle was going: its
    velocity points within 45 degrees of its net displacement from its first to its last
    detected box, a displacement of at least one box scale."""
    edges = tracks.last_box[i] - tracks.origin[i]
    way = (edges[:2] + edges[2:]) / 2
    v = tracks.x[i, 2:4]
    far = np.hypot(*way) >= tracks.scale[i]
    return bool(far and way @ v >= np.cos(np.pi / 4) * np.hypot(*way) * np.hypot(*v))


def drop_coasted_tail(rows: deque[np.ndarray]) -> None:
    """Remove the coasted rows (conf < 1) at the end of `rows`: the stretch since the last
    detection."""
    while rows and rows[-1][6] < 1.0:
        rows.pop()
