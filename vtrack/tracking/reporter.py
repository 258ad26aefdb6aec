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
trailing predictions are dropped.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from vtrack.tracking.table import TrackTable

ROW_COLUMNS = ("frame", "id", "x", "y", "w", "h", "conf")  # conf 1 = detected, < 1 = coasted
ON_COURSE_IOU = 0.5  # a re-acquisition this close to the prediction confirms the coasted rows


class RowReporter:
    """Holds the rows not yet final, by track uid."""

    MAX_PENDING = 4096  # rows kept for a track not yet confirmed (static clutter is bounded)

    def __init__(self, max_coast_seconds: float) -> None:
        self.max_coast = max_coast_seconds
        self.pending: dict[int, deque[np.ndarray]] = {}

    def rows(self, frame: int, t: float, tracks: TrackTable, boxes: np.ndarray,
             hit: np.ndarray, on_course: np.ndarray, inside: np.ndarray, alive: np.ndarray
             ) -> np.ndarray:
        """The rows (R, 7) of ROW_COLUMNS that became final this frame; `boxes` are the
        tracks' boxes clipped to the image; on_course marks the hit tracks whose detection
        confirms their prediction. conf is 1 for a detected row and falls from 0.95 to 0.05
        over the coasting limit."""
        conf = np.where(hit, 1.0,
                        np.clip(1.0 - (t - tracks.hist_t[:, 0]) / (self.max_coast + 1e-9),
                                0.05, 0.95))
        rows = np.column_stack([np.full(len(tracks), frame), tracks.id, boxes, conf])
        # A prediction at the image edge can clip to an empty box: such a row has no position
        # in the image and is not reported (INTERFACE: w, h > 0).
        visible = (boxes[:, 2] >= 1.0) & (boxes[:, 3] >= 1.0)
        waiting = np.fromiter(self.pending, dtype=int, count=len(self.pending))
        has_pending = np.isin(tracks.uid, waiting)
        confirmed = tracks.id > 0
        simple = confirmed & hit & inside & alive & ~has_pending & visible
        out = [rows[simple]]
        for i in np.flatnonzero(~simple):
            uid = int(tracks.uid[i])
            if not alive[i]:
                self.pending.pop(uid, None)
                continue
            if not inside[i]:
                tail = self.pending.pop(uid, [])
                if confirmed[i] and leaves_on_its_way(tracks, i):
                    out.extend(tail)
                continue
            if hit[i] and not on_course[i] and uid in self.pending:
                drop_coasted_tail(self.pending[uid])
            if visible[i]:
                self.pending.setdefault(uid, deque(maxlen=self.MAX_PENDING)).append(rows[i])
            if confirmed[i] and hit[i] and uid in self.pending:
                back = np.array(self.pending.pop(uid))
                back[:, 1] = tracks.id[i]
                out.append(back)
        return np.vstack(out) if out else np.zeros((0, 7))


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
