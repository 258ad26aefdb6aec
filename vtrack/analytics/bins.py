"""Time-binned crossing counts (counts.csv): one row per (bin, line, direction, class).

Bin b covers [b S, (b + 1) S) seconds of video time (S = --bin-seconds); a crossing falls in
the bin of its own time. Its class is known only once its track has ended (the length is
estimated over the whole track), so crossings are added when their track ends. A bin is
final -- written and forgotten, so memory stays flat -- once no live track has a crossing in
it or earlier and the video time has passed its end by `settle_s` (rows of a track awaiting
confirmation arrive late); a crossing that still arrives for a written bin is added to the
oldest open bin, so the sums over bins always equal summary.json `counts`. Zeros are written;
a class `unknown` row (a calibrated track whose length could not be measured) only when its
count is not zero. The last bin ends with the run.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field

DIRECTIONS = ("forward", "backward")


@dataclass
class CountBins:
    """Crossing counts per open bin; `pop_final` hands out the rows of the settled bins."""

    bin_seconds: float
    line_labels: Sequence[str]
    classes: Sequence[str]                     # ("all",) without a calibration
    settle_s: float = 120.0
    _open: dict[int, dict[tuple[int, str, str], int]] = field(
        default_factory=lambda: defaultdict(lambda: defaultdict(int)))
    _next: int | None = None                   # the first bin not yet written

    def bin_of(self, time: float) -> int:
        return int(math.floor(time / self.bin_seconds))

    def start(self, time: float) -> None:
        """The run's first frame time: bins are written from its bin on."""
        if self._next is None:
            self._next = self.bin_of(time)

    def add(self, time: float, line: int, direction: str, cls: str) -> None:
        assert self._next is not None, "start() first"
        b = max(self.bin_of(time), self._next)
        self._open[b][(line, direction, cls)] += 1

    def pop_final(self, now: float, pending_from: float | None,
                  run_end: float | None = None) -> list[list]:
        """Rows of every bin that is settled at video time `now` (the latest frame's) and
        holds no crossing of a live track (`pending_from`: the earliest such crossing time,
        None if none). With `run_end` (the run is over) every bin is written up to the one
        holding `now`, the last one ending at `run_end`."""
        if self._next is None:
            return []
        if run_end is not None:
            last = max([self.bin_of(now)] + list(self._open))
        else:
            last = self.bin_of(now - self.settle_s) - 1
            if pending_from is not None:
                last = min(last, self.bin_of(pending_from) - 1)
        rows = []
        while self._next <= last:
            b = self._next
            counts = self._open.pop(b, {})
            start = b * self.bin_seconds
            stop = start + self.bin_seconds
            if run_end is not None and b == last:
                stop = max(min(stop, run_end), start)
            classes = list(self.classes) + sorted(
                {c for (_, _, c), n in counts.items() if n and c not in self.classes})
            for line, label in enumerate(self.line_labels):
                for direction in DIRECTIONS:
                    for cls in classes:
                        n = counts.get((line, direction, cls), 0)
                        if n or cls in self.classes:
                            rows.append([_num(start), _num(stop), label, direction, cls, n])
            self._next = b + 1
        return rows


def _num(v: float) -> str:
    return f"{v:g}" if float(v).is_integer() else f"{v:.4f}"
