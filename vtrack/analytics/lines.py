"""Counting lines (INTERFACE.md): a track counts at most once per line, in the direction of
its first crossing of the segment. With c(p) = (x2-x1)(py-y1) - (y2-y1)(px-x1), forward means
c goes from negative to positive (for a line from (0, y) to (W, y): moving down the image).

A path that touches the line and turns back does not cross; one that flickers across it
counts once, since a track counts once per line.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Crossing:
    frame: int
    time: float
    id: int
    line: int
    direction: str  # "forward" | "backward"


def _side(line: np.ndarray, p: np.ndarray) -> float:
    x1, y1, x2, y2 = line
    return float((x2 - x1) * (p[1] - y1) - (y2 - y1) * (p[0] - x1))


def _within_segment(line: np.ndarray, a: np.ndarray, b: np.ndarray, ca: float, cb: float) -> bool:
    """Whether the path step a->b (already on opposite sides) meets the segment itself."""
    x1, y1, x2, y2 = line
    s = ca / (ca - cb)                       # where the step meets the infinite line
    p = a + s * (b - a)
    d = np.array([x2 - x1, y2 - y1])
    u = float(np.dot(p - (x1, y1), d) / np.dot(d, d))
    return 0.0 <= u <= 1.0


@dataclass
class LineCounter:
    """Counts track crossings of several lines, fed each track's box centres in time order.

    Memory stays flat on an endless stream: `add` returns the crossings it finds instead of
    keeping them, the counts are running totals, and `forget` drops a finished track.
    """

    lines: Sequence[Sequence[float]]
    _last: dict[int, tuple[np.ndarray, list[float]]] = field(default_factory=dict)
    _counted: set[tuple[int, int]] = field(default_factory=set)

    def __post_init__(self) -> None:
        self._lines = [np.asarray(l, dtype=float) for l in self.lines]
        self._totals = {(k, d): 0 for k in range(len(self._lines))
                        for d in ("forward", "backward")}

    def add(self, track_id: int, frame: int, time: float, center: np.ndarray) -> list[Crossing]:
        """Feed one path point of a track (frames of one track must come in order); returns
        the crossings this step of its path makes."""
        found = []
        p = np.asarray(center, dtype=float)
        sides = [_side(l, p) for l in self._lines]
        prev = self._last.get(track_id)
        if prev is not None:
            a, last_sides = prev
            for k, line in enumerate(self._lines):
                ca, cb = last_sides[k], sides[k]
                if cb == 0.0:                  # on the line: keep the side it came from
                    sides[k] = ca
                    continue
                if ca == 0.0 or (ca < 0) == (cb < 0) or (track_id, k) in self._counted:
                    continue
                if _within_segment(line, a, p, ca, cb):
                    self._counted.add((track_id, k))
                    found.append(Crossing(frame, time, track_id, k,
                                          "forward" if ca < 0 else "backward"))
                    self._totals[k, found[-1].direction] += 1
        self._last[track_id] = (p, sides)
        return found

    def forget(self, track_id: int) -> None:
        """Drop a track that will get no more path points (its crossings stay counted)."""
        self._last.pop(track_id, None)
        for k in range(len(self._lines)):
            self._counted.discard((track_id, k))

    def counts(self) -> list[dict]:
        """Per line: {"line": [...], "forward": n, "backward": n, "total": n}."""
        out = []
        for k, line in enumerate(self._lines):
            fw, bw = self._totals[k, "forward"], self._totals[k, "backward"]
            out.append({"line": [float(v) for v in line], "forward": fw, "backward": bw,
                        "total": fw + bw})
        return out
