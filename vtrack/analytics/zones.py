"""Zone occupancy: when each vehicle enters and leaves each polygon zone, and for how long.

A vehicle is in a zone when its ground contact point -- the bottom centre of its box, where
the vehicle meets the road -- is inside the polygon (a box centre would put a tall vehicle in a
zone drawn on the road before it gets there). Entries and exits are debounced: a change of
in/out counts once the new side has held for the zone's `debounce_s` (a track jittering on the
border produces no events), and it is dated from the first frame of the new side, so the
times are not delayed by the debounce. A pending change is dropped when the track ends.

An event's exit is the first frame the vehicle is out again; dwell = exit time - enter time.
A vehicle whose track ends inside (the run ends, or the track is lost or leaves the image
inside the zone) has no exit: its dwell is up to its last row (a lower bound).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from vtrack.analytics.regions import contains


@dataclass
class ZoneEvent:
    """One stay of a vehicle in a zone (a row of zone_events.csv)."""

    id: int
    zone: str
    enter_frame: int
    enter_time: float
    exit_frame: int | None
    end_time: float          # exit time, or the time of the last row inside

    @property
    def dwell_s(self) -> float:
        return self.end_time - self.enter_time

    def row(self) -> list:
        return [self.id, self.zone, self.enter_frame,
                "" if self.exit_frame is None else self.exit_frame,
                f"{self.enter_time:.4f}", f"{self.dwell_s:.4f}"]


@dataclass
class _Presence:
    """One track's state for one zone."""

    inside: bool
    since: tuple[int, float] | None = None      # (frame, time) the other side was first seen
    enter: tuple[int, float] | None = None      # the open stay
    last_time: float = 0.0


@dataclass
class _ZoneStats:
    """Running figures of one zone. Occupancy is evaluated at each entry's own (back-dated)
    time, from the stays open then: the ones still open, and the recent ones whose exit came
    later (an exit is committed up to debounce_s after the time it is dated with)."""

    entries: int = 0
    max_occupancy: int = 0
    dwell_sum: float = 0.0
    events: int = 0
    open: dict[int, float] = field(default_factory=dict)          # track -> enter time
    recent: deque = field(default_factory=deque)                   # (enter, exit) times

    def enter(self, track_id: int, time: float, now: float, keep_s: float) -> None:
        while self.recent and self.recent[0][1] < now - keep_s:
            self.recent.popleft()
        occupancy = 1 + sum(t <= time for t in self.open.values()) + sum(
            a <= time < b for a, b in self.recent)
        self.open[track_id] = time
        self.entries += 1
        self.max_occupancy = max(self.max_occupancy, occupancy)

    def leave(self, track_id: int, time: float, dwell: float) -> None:
        self.recent.append((self.open.pop(track_id), time))
        self.dwell_sum += dwell
        self.events += 1


@dataclass
class ZoneCounter:
    """Feed each track's ground points in time order; collects finished stays."""

    names: Sequence[str]
    polygons: Sequence[np.ndarray]           # pixels
    debounce_s: Sequence[float]
    _state: dict[int, list[_Presence]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._stats = [_ZoneStats() for _ in self.names]

    def add(self, track_id: int, frame: int, time: float, point: np.ndarray) -> list[ZoneEvent]:
        """One ground point of a track; returns the stays it ends."""
        states = self._state.get(track_id)
        inside = [contains(poly, point) for poly in self.polygons]
        if states is None:         # a new track starts outside; its first point may enter
            self._state[track_id] = states = [_Presence(False) for _ in self.names]
        out = []
        for z, (st, now_in) in enumerate(zip(states, inside)):
            if now_in == st.inside:
                st.since = None
            elif st.since is None:
                st.since = (frame, time)
            if st.since is not None and time - st.since[1] >= self.debounce_s[z]:
                since, st.since = st.since, None
                if now_in:
                    self._enter(st, z, track_id, since[0], since[1], time)
                else:
                    out.append(self._leave(st, z, track_id, since[0], since[1]))
            if st.inside:
                st.last_time = time
        return out

    def end_track(self, track_id: int) -> list[ZoneEvent]:
        """The track is over: its open stays are returned with an empty exit."""
        out = []
        for z, st in enumerate(self._state.pop(track_id, [])):
            if st.inside:
                out.append(self._leave(st, z, track_id, None, st.last_time))
        return out

    def _enter(self, st: _Presence, z: int, track_id: int, frame: int, time: float,
               now: float) -> None:
        st.inside, st.enter, st.last_time = True, (frame, time), time
        self._stats[z].enter(track_id, time, now, 2.0 * self.debounce_s[z] + 1.0)

    def _leave(self, st: _Presence, z: int, track_id: int, frame: int | None,
               time: float) -> ZoneEvent:
        assert st.enter is not None
        ev = ZoneEvent(track_id, self.names[z], st.enter[0], st.enter[1], frame, time)
        st.inside, st.enter = False, None
        self._stats[z].leave(track_id, time, ev.dwell_s)
        return ev

    def summary(self) -> list[dict]:
        """summary.json `zones`: entries, max occupancy, the mean dwell of the stays written
        so far (the mean of zone_events.csv's dwell_s for the zone) and the polygon (px)."""
        return [{"name": n, "entries": s.entries, "max_occupancy": s.max_occupancy,
                 "mean_dwell_s": round(s.dwell_sum / s.events, 4) if s.events else 0.0,
                 "polygon": [[round(float(x), 2), round(float(y), 2)] for x, y in poly]}
                for n, s, poly in zip(self.names, self._stats, self.polygons)]
