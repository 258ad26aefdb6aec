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

Each track is, for the reporter, in one of five states, read from what the reporter holds
for it and the track's flags: `tentative` (not confirmed: every row held), `confirmed`
(nothing held: its rows are final as they come), `coasting` (confirmed, the predicted rows
since its last detection held), `standing` (confirmed and held in place: its rows held, not
smoothed) and `ended` (gone). Each frame brings each track one event, the first that
applies: `lost` (past its coasting limit, or a duplicate), `left` (its prediction left the
image), `detected`, `missed`. `TRANSITIONS` is the whole machine: the actions each (state,
event) runs, in order, and the state they lead to (where the row is visible; an invisible
row is not held).

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
from enum import Enum
from typing import NamedTuple

import numpy as np

from vtrack.boxes import from_centre, in_image
from vtrack.estimation.kalman import smooth_gap
from vtrack.tracking.lifecycle import MIN_INSIDE_SHARE
from vtrack.tracking.table import TrackTable

ROW_COLUMNS = ("frame", "id", "x", "y", "w", "h", "conf")  # conf 1 = detected, < 1 = coasted
ON_COURSE_IOU = 0.5  # a re-acquisition this close to the prediction confirms the coasted rows


class State(Enum):
    TENTATIVE = "tentative"
    CONFIRMED = "confirmed"
    COASTING = "coasting"
    STANDING = "standing"
    ENDED = "ended"


class Event(Enum):
    LOST = "lost"            # past its coasting limit, or a duplicate of an older track
    LEFT = "left"            # its predicted box left the image
    DETECTED = "detected"
    MISSED = "missed"


# The actions (RowReporter methods, run in order):
# drop     forget the held rows and coasted stretch;
# leave    release the held rows if the track left on its vehicle's way (`leaves_on_its_way`),
#          else drop them;
# emit     report this frame's row at once (when visible);
# settle   a detection ends a coasted stretch: smooth the held coasted rows where it confirms
#          the prediction (on course), drop them where it does not; forget the stretch;
# hold     hold this frame's row (when visible);
# coast    remember the row's predicted state for smoothing (a standing track: forget it);
# release  report the held rows with the track's id, once the track is confirmed.
_COASTING = {Event.LOST: (State.ENDED, ("drop",)),
             Event.LEFT: (State.ENDED, ("leave",)),
             Event.DETECTED: (State.CONFIRMED, ("settle", "hold", "release")),
             Event.MISSED: (State.COASTING, ("hold", "coast"))}
TRANSITIONS: dict[tuple[State, Event], tuple[State, tuple[str, ...]]] = {
    (State.TENTATIVE, Event.LOST): (State.ENDED, ("drop",)),
    (State.TENTATIVE, Event.LEFT): (State.ENDED, ("drop",)),
    # -> confirmed (its rows released) on the frame the confirmer gives it an id
    (State.TENTATIVE, Event.DETECTED): (State.TENTATIVE, ("settle", "hold", "release")),
    (State.TENTATIVE, Event.MISSED): (State.TENTATIVE, ("hold", "coast")),
    (State.CONFIRMED, Event.LOST): (State.ENDED, ("drop",)),
    (State.CONFIRMED, Event.LEFT): (State.ENDED, ("leave",)),
    (State.CONFIRMED, Event.DETECTED): (State.CONFIRMED, ("emit",)),
    # -> standing when the track stops (lifecycle.record_hits)
    (State.CONFIRMED, Event.MISSED): (State.COASTING, ("hold", "coast")),
    **{(State.COASTING, e): outcome for e, outcome in _COASTING.items()},
    **{(State.STANDING, e): outcome for e, outcome in _COASTING.items()},
}


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
        after them and have no coasted rows). conf is 1 for a detected row and falls from
        0.95 to 0.05 over the coasting limit. Each track's (state, event) runs the actions
        of TRANSITIONS; confirmed tracks detected come first, in one block."""
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
        states = self.states(tracks)
        events = np.select([~alive, ~inside, hit], [Event.LOST, Event.LEFT, Event.DETECTED],
                           Event.MISSED)
        block = (states == State.CONFIRMED) & (events == Event.DETECTED) & visible
        out = [rows[block]]
        step = _Step(self, frame, t, tracks, rows, visible, on_course, prior_x, prior_P, out)
        for i in np.flatnonzero(~block):
            for action in TRANSITIONS[states[i], events[i]][1]:
                getattr(step, action)(i)
        return np.vstack(out) if out else np.zeros((0, 7))

    def states(self, tracks: TrackTable) -> np.ndarray:
        """(N,) each track's State before this frame's event (module docstring)."""
        held = np.isin(tracks.uid, np.fromiter(self.pending, dtype=int,
                                               count=len(self.pending)))
        return np.select([tracks.id == 0, ~held, tracks.standing],
                         [State.TENTATIVE, State.CONFIRMED, State.STANDING], State.COASTING)

    def _smooth(self, rows: deque[np.ndarray], stretch: list[CoastedRow], t: float,
                x_post: np.ndarray, x_prior: np.ndarray, P_prior: np.ndarray) -> None:
        """Move the coasted rows of `stretch` (in `rows`) onto their smoothed centres, in
        place, where the predicted and the smoothed box both lie inside the image."""
        x = smooth_gap(np.array([c.x for c in stretch]), np.array([c.P for c in stretch]),
                       np.array([self.transition(t - c.t) for c in stretch]),
                       x_prior, P_prior, x_post)
        moved = {}
        for c, xs in zip(stretch, x, strict=True):
            before, after = from_centre(c.x[:2], c.size), from_centre(xs[:2], c.size)
            if in_image(before, self.width, self.height) and in_image(after, self.width,
                                                                      self.height):
                moved[c.frame] = after
        for r in rows:
            if r[6] < 1.0 and int(r[0]) in moved:
                r[2:6] = moved[int(r[0])]


class _Step:
    """The actions of TRANSITIONS on one frame's rows (RowReporter.rows)."""

    def __init__(self, reporter: RowReporter, frame: int, t: float, tracks: TrackTable,
                 rows: np.ndarray, visible: np.ndarray, on_course: np.ndarray,
                 prior_x: np.ndarray, prior_P: np.ndarray, out: list[np.ndarray]) -> None:
        self.r, self.frame, self.t, self.tracks = reporter, frame, t, tracks
        self.rows, self.visible, self.on_course = rows, visible, on_course
        self.prior_x, self.prior_P, self.out = prior_x, prior_P, out

    def drop(self, i: int) -> None:
        uid = int(self.tracks.uid[i])
        self.r.pending.pop(uid, None)
        self.r.coasted.pop(uid, None)

    def leave(self, i: int) -> None:
        uid = int(self.tracks.uid[i])
        self.r.coasted.pop(uid, None)
        tail = self.r.pending.pop(uid, [])
        if leaves_on_its_way(self.tracks, i):
            self.out.extend(tail)

    def emit(self, i: int) -> None:
        if self.visible[i]:
            self.out.append(self.rows[i:i + 1])

    def settle(self, i: int) -> None:
        r, uid = self.r, int(self.tracks.uid[i])
        if not self.on_course[i] and uid in r.pending:
            drop_coasted_tail(r.pending[uid])
        elif uid in r.coasted and uid in r.pending:
            r._smooth(r.pending[uid], r.coasted[uid], self.t, self.tracks.x[i],
                      self.prior_x[i], self.prior_P[i])
        r.coasted.pop(uid, None)

    def hold(self, i: int) -> None:
        if self.visible[i]:
            uid = int(self.tracks.uid[i])
            self.r.pending.setdefault(uid, deque(maxlen=self.r.MAX_PENDING)).append(
                self.rows[i])

    def coast(self, i: int) -> None:
        r, tracks, uid = self.r, self.tracks, int(self.tracks.uid[i])
        if not self.visible[i]:
            return
        if tracks.standing[i]:     # held on purpose, not predicted: not smoothed
            r.coasted.pop(uid, None)
        elif r.transition is not None:
            r.coasted.setdefault(uid, []).append(CoastedRow(
                self.frame, self.t, tracks.x[i].copy(), tracks.P[i].copy(),
                tracks.size[i].copy()))

    def release(self, i: int) -> None:
        uid = int(self.tracks.uid[i])
        if self.tracks.id[i] > 0 and uid in self.r.pending:
            back = np.array(self.r.pending.pop(uid))
            back[:, 1] = self.tracks.id[i]
            self.out.append(back)


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
