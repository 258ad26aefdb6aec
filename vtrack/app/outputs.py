"""The track run's output files, valid at any moment, with memory that stays flat.

A `Sink` consumes the tracker's output frame by frame (`TrackedFrame`) and owns some output
files. The pipeline calls `flush` after the first frame, at least every --flush-seconds
and at the end; each flush brings the sink's files up to date on disk and returns its
entries for summary.json. Sinks keep only what can still change: a file grows by
appending (`fileio.GrowingFile`), never by rewriting it from the start, and whatever
belongs to a track is dropped once the track has ended (`TrackedFrame.ended`).

tracks.csv must be sorted by frame then id, but the tracker emits some rows late (a
tentative track's rows once it is confirmed, coasted rows once the vehicle is re-acquired),
never `Tracker.max_row_lag` frames late or more. `TracksCsv` is a reorder buffer: rows of
frames at least that old are final and appended for good; the newer ones form the file's
provisional tail, rewritten (sorted) at each flush.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from vtrack.analytics.traffic import TrafficAnalytics
from vtrack.fileio import GrowingFile
from vtrack.tracking.tracker import FrameTracks


class FrameTimes:
    """The times of the last `keep` frames (frames are numbered 1, 2, ... without gaps)."""

    def __init__(self, keep: int) -> None:
        self._times: deque[float] = deque(maxlen=keep)
        self._first = 1          # frame number of _times[0]

    def add(self, index: int, time: float) -> None:
        if index != self._first + len(self._times):
            raise ValueError(f"frame {index} out of order")
        if len(self._times) == self._times.maxlen:
            self._first += 1
        self._times.append(time)

    def __getitem__(self, index: int) -> float:
        if index < self._first:
            raise KeyError(f"frame {index} is no longer kept")
        return self._times[index - self._first]


@dataclass(frozen=True)
class TrackedFrame:
    """What every sink receives after the tracker's step on one frame."""

    index: int              # 1-based frame number (tracks.csv's first column)
    time: float             # seconds since the first frame
    tracks: FrameTracks     # the tracker's output; its rows may be of earlier frames
    ended: list[int]        # track ids whose last row came with this frame or before
    times: FrameTimes       # the time of any frame a row may still be of
    # (K,) per confirmed track of `tracks`: the appearance class (index into
    # vision.appearance.VEHICLE_CLASSES, -1 none) and score of this frame's detection
    looks: np.ndarray | None = None
    looks_score: np.ndarray | None = None


class Sink(Protocol):
    """A per-frame consumer of the tracker's output that owns some output files."""

    def frame(self, f: TrackedFrame) -> None:
        """Take one frame's output (called for every frame, in order)."""

    def flush(self, final: bool = False) -> dict[str, Any]:
        """Bring the files up to date on disk; return the entries for summary.json."""

    def close(self) -> None:
        """Release open files (after the last flush)."""


class TrackEnds:
    """Which track ids have ended after each step: ids seen (among the confirmed tracks or
    in the rows) that are no longer among the tracker's tracks nor held for a vehicle that
    may come back (FrameTracks.held). A deleted track's last rows come out in the step that
    deletes it, so none of its rows follow."""

    def __init__(self) -> None:
        self._active: set[int] = set()

    def update(self, tracks: FrameTracks) -> list[int]:
        current = set(tracks.ids.tolist()) | set(tracks.held.tolist())
        seen = self._active | set(tracks.rows[:, 1].astype(int).tolist())
        self._active = current
        return sorted(seen - current)


def mot_lines(rows: np.ndarray, chunk: int = 4096) -> Iterator[bytes]:
    """tracks.csv lines (MOTChallenge) for rows of ROW_COLUMNS, `chunk` rows at a time (a
    few hundred kB, not the whole tail at once); x, y, z are -1."""
    for k in range(0, len(rows), chunk):
        yield "".join(f"{int(r[0])},{int(r[1])},{r[2]:.2f},{r[3]:.2f},{r[4]:.2f},{r[5]:.2f},"
                      f"{r[6]:.3f},-1,-1,-1\n" for r in rows[k:k + chunk].tolist()).encode()


class TracksCsv:
    """tracks.csv through a reorder buffer (see the module's docstring); summary `tracks`."""

    def __init__(self, path: Path, max_row_lag: int) -> None:
        self.file = GrowingFile(path)
        self.max_row_lag = max_row_lag
        self._tail = np.zeros((0, 7))         # rows not yet final, sorted
        self._blocks: list[np.ndarray] = []   # rows since the last flush, as emitted
        self._frame = 0
        self._ids = 0                         # distinct ids so far
        self._open_ids: set[int] = set()      # counted ids that may still emit rows

    def frame(self, f: TrackedFrame) -> None:
        self._frame = f.index
        if len(f.tracks.rows):
            self._blocks.append(f.tracks.rows)
            new = set(f.tracks.rows[:, 1].astype(int).tolist()) - self._open_ids
            self._ids += len(new)
            self._open_ids |= new
        self._open_ids.difference_update(f.ended)

    def flush(self, final: bool = False) -> dict[str, Any]:
        rows = np.concatenate([self._tail, *self._blocks])
        rows = rows[np.lexsort((rows[:, 1], rows[:, 0]))]
        cut = int(np.searchsorted(rows[:, 0], self._frame - self.max_row_lag, side="right"))
        self.file.write(mot_lines(rows[:cut]), mot_lines(rows[cut:]))
        self._tail, self._blocks = rows[cut:], []   # only once written (an interrupt
        return {"tracks": self._ids}                # during the write loses nothing)

    def close(self) -> None:
        self.file.close()


class TrafficSink:
    """The traffic analytics (vtrack.analytics.traffic: crossings.csv, vehicles.csv,
    counts.csv, zone_events.csv; summary `counts`, `zones`, `calibration`) as a sink."""

    def __init__(self, analytics: TrafficAnalytics) -> None:
        self.analytics = analytics

    def frame(self, f: TrackedFrame) -> None:
        self.analytics.add_frame(f.index, f.time, f.tracks, f.looks, f.looks_score)

    def flush(self, final: bool = False) -> dict[str, Any]:
        return self.analytics.flush(final)

    def close(self) -> None:
        """Nothing held open (the analytics append at each flush)."""


class DetectionsCsv:
    """detections.csv (--save-detections): the detector's boxes of every frame as
    MOTChallenge detection rows `frame,-1,x,y,w,h,conf,-1,-1,-1`, appended at each flush;
    conf is the appearance score of a box the appearance model drew, 1 for a motion-only
    blob."""

    def __init__(self, path: Path) -> None:
        self.file = GrowingFile(path)
        self._blocks: list[np.ndarray] = []

    def add(self, index: int, boxes: np.ndarray, scores: np.ndarray | None = None) -> None:
        """The boxes (D, 4) of frame `index` and their conf (D,) (None: all 1)."""
        if len(boxes):
            conf = np.ones(len(boxes)) if scores is None else scores
            self._blocks.append(np.column_stack([np.full(len(boxes), index), boxes, conf]))

    def frame(self, f: TrackedFrame) -> None:
        """Detections come through `add`."""

    def flush(self, final: bool = False) -> dict[str, Any]:
        rows = np.concatenate(self._blocks) if self._blocks else np.zeros((0, 6))
        self._blocks = []
        self.file.write(final=["".join(f"{int(r[0])},-1,{r[1]:.2f},{r[2]:.2f},{r[3]:.2f},"
                                       f"{r[4]:.2f},{_conf(r[5])},-1,-1,-1\n"
                                       for r in rows.tolist()).encode()])
        return {}

    def close(self) -> None:
        self.file.close()


def _conf(score: float) -> str:
    """detections.csv's conf: 1 as before for motion blobs, a score to 4 decimals."""
    return "1" if score >= 1.0 else f"{score:.4f}"
