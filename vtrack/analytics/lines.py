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

    Memory stays flat on an endless stream: the tallies are per line, the crossings are
    returned by `add` (not kept), and a finished track's state goes with `forget`."""

    lines: Sequence[Sequence[float]]
    _last: dict[int, tuple[np.ndarray, list[float]]] = field(default_factory=dict)
    _counted: dict[int, set[int]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._lines = [np.asarray(l, dtype=float) for l in self.lines]
        self._tally = np.zeros((len(self._lines), 2), dtype=np.int64)  # forward, backward

    def add(self, track_id: int, frame: int, time: float, center: np.ndarray) -> list[Crossing]:
        """Feed one path point of a track (frames of one track must come in order); returns
        the crossings it completes."""
        p = np.asarray(center, dtype=float)
        sides = [_side(l, p) for l in self._lines]
        prev = self._last.get(track_id)
        out: list[Crossing] = []
        if prev is not None:
            a, last_sides = prev
            counted = self._counted.setdefault(track_id, set())
            for k, line in enumerate(self._lines):
                ca, cb = last_sides[k], sides[k]
                if cb == 0.0:                  # on the line: keep the side it came from
                    sides[k] = ca
                    continue
                if ca == 0.0 or (ca < 0) == (cb < 0) or k in counted:
                    continue
                if _within_segment(line, a, p, ca, cb):
                    counted.add(k)
                    forward = ca < 0
                    self._tally[k, 0 if forward else 1] += 1
                    out.append(Crossing(frame, time, track_id, k,
                                        "forward" if forward else "backward"))
        self._last[track_id] = (p, sides)
        return out

    def forget(self, track_id: int) -> None:
        """Drop a finished track's state."""
        self._last.pop(track_id, None)
        self._counted.pop(track_id, None)

    def counts(self) -> list[dict]:
        """Per line: {"line": [...], "forward": n, "backward": n, "total": n}."""
        return [{"line": [float(v) for v in line], "forward": int(fw), "backward": int(bw),
                 "total": int(fw + bw)} for line, (fw, bw) in zip(self._lines, self._tally)]


def count_rows(rows: np.ndarray, lines: Sequence[Sequence[float]]) -> list[list[int]]:
    """[forward, backward] per line for MOT rows (frame, id, x, y, w, h, ...): every id's box
    centres in frame order through one LineCounter, the rule `vtrack track` counts by (used
    on a peer's tracks and on a synthetic clip's ground truth)."""
    counter = LineCounter(lines)
    rows = np.asarray(rows, dtype=float)
    for r in rows[np.lexsort((rows[:, 0], rows[:, 1]))] if rows.size else ():
        counter.add(int(r[1]), int(r[0]), 0.0, r[2:4] + r[4:6] / 2)
    return [[c["forward"], c["backward"]] for c in counter.counts()]
