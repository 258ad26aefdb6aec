"""Turning movements: which gate each vehicle came through and which it left by.

A track passes a gate when the path of its box centre (the rows of tracks.csv, coasted rows
included, as for count lines) crosses the gate's line -- the count lines' rule, through
lines.LineCounter, either direction -- or has a point inside its polygon (regions.contains;
a track that starts inside has entered it). Each gate is passed at most once per track, at the
time of its first pass. A track that passed two or more distinct gates makes one movement,
from the gate it passed first to the one it passed last, dated by the last pass (the bin of
movements.csv); it is known once the track has ended.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from vtrack.analytics.lines import LineCounter
from vtrack.analytics.regions import contains


@dataclass(frozen=True)
class Movement:
    """One vehicle's movement: gate names and the time it reached the last gate."""

    id: int
    origin: str
    destination: str
    time: float


@dataclass
class GateCounter:
    """Gate passes per live track, fed each track's box centres in time order (like
    LineCounter); `end_track` gives the finished track's movement. Memory per live track."""

    names: Sequence[str]
    shapes: Sequence[np.ndarray]          # (2, 2) segment or (n, 2) polygon, pixels
    is_line: Sequence[bool]
    _passes: dict[int, dict[int, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._line_gates = [g for g, line in enumerate(self.is_line) if line]
        self._polygons = [(g, np.asarray(s, dtype=float))
                          for g, (s, line) in enumerate(zip(self.shapes, self.is_line))
                          if not line]
        self._lines = LineCounter([np.asarray(self.shapes[g], dtype=float).ravel()
                                   for g in self._line_gates])
        self.tally = np.zeros((len(self.names), len(self.names)), dtype=np.int64)

    def add(self, track_id: int, frame: int, time: float, center: np.ndarray) -> None:
        """Feed one path point of a track (its frames in order)."""
        passed = self._passes.setdefault(track_id, {})
        for c in self._lines.add(track_id, frame, time, center):
            passed.setdefault(self._line_gates[c.line], time)
        for g, poly in self._polygons:
            if g not in passed and contains(poly, center):
                passed[g] = time

    def end_track(self, track_id: int) -> Movement | None:
        """The track is over: its movement (None if it passed fewer than 2 gates)."""
        self._lines.forget(track_id)
        passed = self._passes.pop(track_id, {})
        if len(passed) < 2:
            return None
        order = sorted(passed, key=lambda g: (passed[g], g))
        first, last = order[0], order[-1]
        self.tally[first, last] += 1
        return Movement(track_id, self.names[first], self.names[last], passed[last])

    def pending_from(self) -> float | None:
        """The earliest time a live track's movement can still be dated with: the latest
        pass of each live track that passed a gate (a movement is dated by its last pass)."""
        times = [max(p.values()) for p in self._passes.values() if p]
        return min(times) if times else None

    def pairs(self) -> list[tuple[str, str]]:
        """Every ordered pair of distinct gates (movements.csv's keys), origin-major."""
        return [(a, b) for a in self.names for b in self.names if a != b]

    def summary(self) -> list[dict]:
        """summary.json `movements`: the finished movements per ordered pair of gates."""
        index = {n: k for k, n in enumerate(self.names)}
        return [{"from": a, "to": b, "count": int(self.tally[index[a], index[b]])}
                for a, b in self.pairs()]
