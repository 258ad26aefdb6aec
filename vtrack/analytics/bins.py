"""Time bins of the binned outputs (counts.csv, movements.csv, speeds.csv): events per
(bin, key, class), written once the bin is final.

Bin b covers [b S, (b + 1) S) seconds of video time (S = --bin-seconds); an event falls in
the bin of its own time (a line crossing's, a movement's arrival at its last gate). Its class
is known only once its track has ended (the length is estimated over the whole track), so
events are added when their track ends. A bin is final -- written and forgotten, so memory
stays flat -- once no live track has an event in it or earlier and the video time has passed
its end by `settle_s` (rows of a track awaiting confirmation arrive late); an event that still
arrives for a written bin is added to the oldest open bin, so the sums over bins always equal
summary.json's totals. Zeros are written for every key and listed class; a class `unknown`
row (a calibrated track whose length could not be measured) only when it has events. The
last bin ends with the run.

speeds.csv's statistics per (bin, line, direction, class): count, mean, the 50th and 85th
percentiles (linear interpolation between order statistics, numpy's default) and the maximum;
empty cells where the count is 0.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field

import numpy as np

DIRECTIONS = ("forward", "backward")

Bin = tuple[float, float, dict[tuple[Hashable, str], list[float]]]   # start, stop, values


@dataclass
class TimeBins:
    """Event values per open bin and (key, class); `pop_final` hands out the settled bins."""

    bin_seconds: float
    settle_s: float = 120.0
    _open: dict[int, dict[tuple[Hashable, str], list[float]]] = field(
        default_factory=lambda: defaultdict(lambda: defaultdict(list)))
    _next: int | None = None                   # the first bin not yet written

    def bin_of(self, time: float) -> int:
        return int(math.floor(time / self.bin_seconds))

    def start(self, time: float) -> None:
        """The run's first frame time: bins are written from its bin on."""
        if self._next is None:
            self._next = self.bin_of(time)

    def add(self, time: float, key: Hashable, cls: str, value: float = 1.0) -> None:
        """One event of `key` and class `cls` at `time` (its value: a speed, or 1 to count)."""
        assert self._next is not None, "start() first"
        b = max(self.bin_of(time), self._next)
        self._open[b][(key, cls)].append(value)

    def pop_final(self, now: float, pending_from: float | None,
                  run_end: float | None = None) -> list[Bin]:
        """The bins that are settled at video time `now` (the latest frame's) and hold no
        event of a live track (`pending_from`: the earliest such event's time, None if none).
        With `run_end` (the run is over) every bin up to the one holding `now`, the last one
        ending at `run_end`."""
        if self._next is None:
            return []
        if run_end is not None:
            last = max([self.bin_of(now)] + list(self._open))
        else:
            last = self.bin_of(now - self.settle_s) - 1
            if pending_from is not None:
                last = min(last, self.bin_of(pending_from) - 1)
        out = []
        while self._next <= last:
            b = self._next
            start = b * self.bin_seconds
            stop = start + self.bin_seconds
            if run_end is not None and b == last:
                stop = max(min(stop, run_end), start)
            out.append((start, stop, self._open.pop(b, {})))
            self._next = b + 1
        return out


def _classes(values: dict, classes: Sequence[str]) -> list[str]:
    """The listed classes, then any other class with events (sorted)."""
    return list(classes) + sorted({c for (_, c), v in values.items() if v and c not in classes})


def count_rows(bins: list[Bin], keys: Sequence[tuple[str, ...]], classes: Sequence[str]
               ) -> list[list]:
    """counts.csv / movements.csv rows: start, stop, *key, class, count per bin, key and
    class (zeros for the listed classes)."""
    rows = []
    for start, stop, values in bins:
        for key in keys:
            for cls in _classes(values, classes):
                n = len(values.get((key, cls), ()))
                if n or cls in classes:
                    rows.append([_num(start), _num(stop), *key, cls, n])
    return rows


def speed_rows(bins: list[Bin], keys: Sequence[tuple[str, ...]], classes: Sequence[str]
               ) -> list[list]:
    """speeds.csv rows: start, stop, *key, class, count, mean, p50, p85, max (km/h) per bin,
    key and class (the listed classes, any other with speeds, then `all`, which the caller
    adds every speed to as well)."""
    rows = []
    for start, stop, values in bins:
        for key in keys:
            for cls in [c for c in _classes(values, classes) if c != "all"] + ["all"]:
                v = np.asarray(values.get((key, cls), ()), dtype=float)
                if not len(v) and cls not in classes and cls != "all":
                    continue
                stats = ([f"{v.mean():.2f}", *(f"{q:.2f}" for q in np.percentile(v, [50, 85])),
                          f"{v.max():.2f}"] if len(v) else ["", "", "", ""])
                rows.append([_num(start), _num(stop), *key, cls, len(v), *stats])
    return rows


def _num(v: float) -> str:
    return f"{v:g}" if float(v).is_integer() else f"{v:.4f}"
