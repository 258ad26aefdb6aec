"""The traffic analytics of one run: fed the tracker's output frame by frame, writes
vehicles.csv, counts.csv, crossings.csv, zone_events.csv, movements.csv and speeds.csv and
gives summary.json its `counts`, `zones`, `movements` and `calibration` keys.

Paths (lines, gates and zones) use the rows of tracks.csv (FrameTracks.rows, some of which
arrive late: back-filled at confirmation, or coasted rows reported at re-acquisition): lines
and gates the box centre, zones the bottom centre of the box. Speeds and lengths use the
filtered states of the frame (FrameTracks.states) with the ground point (x, y + h/2) of
ground.py; a line crossing's speed (speeds.csv) is the road displacement of that ground point
over one second around the crossing (vehicles.SpeedTrace, from the frames vehicles.csv's
speeds use). A track is over when its id leaves FrameTracks.ids (the
tracker reports all of a track's rows by then); its vehicles.csv row, zone stays, movement and
binned counts and speeds are then final and its accumulators are dropped, so memory stays flat
on an endless stream. `flush` creates the files (header first, atomically) and
afterwards only appends the rows that became final, so a periodic flush never rewrites a
growing file.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vtrack.analytics.bins import DIRECTIONS, TimeBins, count_rows, speed_rows
from vtrack.analytics.calibration import Calibration
from vtrack.analytics.camera import camera_from_homography
from vtrack.analytics.ground import (contact_points, contact_velocities, footprint_samples,
                                     speed_sigmas)
from vtrack.analytics.gates import GateCounter
from vtrack.analytics.lines import LineCounter
from vtrack.analytics.regions import CountLine, Gate, Zone
from vtrack.analytics.vehicles import (CLASS_ORDER, CLASSES, MIN_LENGTH_SPEED,
                                       SPEED_SIGMA_MAX, VehicleRecord)
from vtrack.analytics.zones import ZoneCounter
from vtrack.fileio import append_csv, write_csv
from vtrack.vision.appearance import VEHICLE_CLASSES
from vtrack.tracking.tracker import FrameTracks

HEADERS = {
    "vehicles.csv": ["id", "first_frame", "last_frame", "first_time_s", "last_time_s",
                     "detected_frames", "speed_mean_kmh", "speed_max_kmh", "length_m", "class"],
    "counts.csv": ["bin_start_s", "bin_end_s", "line", "direction", "class", "count"],
    "crossings.csv": ["frame", "time_s", "id", "line", "direction"],
    "zone_events.csv": ["id", "zone", "enter_frame", "exit_frame", "enter_time_s", "dwell_s"],
    "movements.csv": ["bin_start_s", "bin_end_s", "from", "to", "class", "count"],
    "speeds.csv": ["bin_start_s", "bin_end_s", "line", "direction", "class", "count",
                   "mean_kmh", "p50_kmh", "p85_kmh", "max_kmh"],
}
TIME_HORIZON_FRAMES = 8192
BORDER_MARGIN = 0.01         # a box this close to the image border (fraction of the image's
                             # larger side) may be cut by it: no speed or length from it   # frame times remembered for rows that arrive late


class TrafficAnalytics:
    """Lines, zones, calibration and time bins of one run written into `out_dir`."""

    def __init__(self, out_dir: str | Path, width: int, height: int, fps: float,
                 lines: Sequence[CountLine] = (), zones: Sequence[Zone] = (),
                 calibration: Calibration | None = None, bin_seconds: float = 60.0,
                 bin_settle_s: float = 120.0, gates: Sequence[Gate] = (),
                 looks_classes: Sequence[str] = ()) -> None:
        """`looks_classes`: the classes an appearance detector gives (none with MOG2
        alone): without a calibration, counts.csv and movements.csv then count per such
        class (and `unknown` for vehicles it never saw) instead of `all`."""
        if calibration is not None:
            calibration.check_frame_size(width, height)
        self.out = Path(out_dir)
        self.width, self.height = width, height
        self.fps = fps if fps > 0 else 25.0
        self.lines = list(lines)
        self.lines_px = [l.pixels(width, height) for l in self.lines]
        self.counter = LineCounter(self.lines_px)
        self.zones = ZoneCounter([z.name for z in zones],
                                 [z.pixels(width, height) for z in zones],
                                 [z.debounce_s for z in zones])
        self.calibration = calibration
        self.camera = (camera_from_homography(calibration.H, width, height)
                       if calibration is not None else None)
        self.gates = GateCounter([g.name for g in gates],
                                 [g.pixels(width, height) for g in gates],
                                 [g.line is not None for g in gates])
        # (name, points in pixels) of every gate and zone, for the annotated frames
        self.regions_px = ([(n, np.asarray(p)) for n, p in zip(self.gates.names,
                                                               self.gates.shapes)]
                           + [(n, np.asarray(p)) for n, p in zip(self.zones.names,
                                                                 self.zones.polygons)])
        known = set(looks_classes)
        self.looks = bool(known)
        if calibration is not None:
            known |= set(CLASSES)
        self.classes = tuple(c for c in CLASS_ORDER if c in known) or ("all",)
        self.line_keys = [(l.name or str(k), d) for k, l in enumerate(self.lines)
                          for d in DIRECTIONS]
        self.bins = TimeBins(bin_seconds, bin_settle_s)             # counts.csv
        self.movement_bins = TimeBins(bin_seconds, bin_settle_s)    # movements.csv
        self.speed_bins = TimeBins(bin_seconds, bin_settle_s)       # speeds.csv
        self.vehicles: dict[int, VehicleRecord] = {}
        self._unresolved: set[int] = set()    # tracks with a crossing awaiting its speed
        self._times: dict[int, float] = {}
        self._pending: dict[str, list[list]] = {name: [] for name in HEADERS}
        self._created = False
        self.frame, self.time = 0, 0.0

    # ------------------------------------------------------------------- feeding
    def add_frame(self, frame: int, time: float, ft: FrameTracks,
                  looks: np.ndarray | None = None, looks_score: np.ndarray | None = None
                  ) -> None:
        """One processed frame: its time (s), the tracks and the rows the tracker emitted;
        `looks` (K,) and `looks_score` (K,), per track of `ft.ids`, the appearance class
        (index into vision.appearance.VEHICLE_CLASSES, -1 none) and score of its detection
        this frame."""
        self.frame, self.time = frame, time
        for bins in (self.bins, self.movement_bins, self.speed_bins):
            bins.start(time)
        self._times[frame] = time
        if len(self._times) > TIME_HORIZON_FRAMES:
            del self._times[next(iter(self._times))]
        rows = ft.rows[np.lexsort((ft.rows[:, 0], ft.rows[:, 1]))] if len(ft.rows) else ft.rows
        for r in rows:
            self._add_row(int(r[0]), int(r[1]), r[2:6], bool(r[6] >= 1.0))
        if self.calibration is not None and len(ft.ids):
            self._sample(ft)
            for tid in list(self._unresolved):
                self._resolve_speeds(tid, final=False)
        if looks is not None:
            for tid, c, score in zip(ft.ids.tolist(), looks.tolist(), looks_score.tolist()):
                if c >= 0:
                    self._record(int(tid), frame, time).looks.add(VEHICLE_CLASSES[c], score)
        alive = set(ft.ids.tolist()) | set(ft.held.tolist())   # held: may come back
        for tid in [t for t in self.vehicles if t not in alive]:
            self._finish(tid)

    def _time_of(self, frame: int) -> float:
        t = self._times.get(frame)
        return t if t is not None else self.time - (self.frame - frame) / self.fps

    def _record(self, tid: int, frame: int, time: float) -> VehicleRecord:
        rec = self.vehicles.get(tid)
        if rec is None:
            rec = self.vehicles[tid] = VehicleRecord(tid, frame, time, frame, time)
        return rec

    def _add_row(self, frame: int, tid: int, box: np.ndarray, detected: bool) -> None:
        t = self._time_of(frame)
        rec = self._record(tid, frame, t)
        rec.add_row(frame, t, detected)
        x, y, w, h = (float(v) for v in box)
        centre = np.array([x + w / 2, y + h / 2])
        for c in self.counter.add(tid, frame, t, centre):
            rec.crossings.append([c.time, c.line, c.direction, None])
            self._unresolved.add(tid)
            self._pending["crossings.csv"].append(
                [c.frame, f"{c.time:.4f}", c.id, self._label(c.line), c.direction])
        self.gates.add(tid, frame, t, centre)
        for ev in self.zones.add(tid, frame, t, np.array([x + w / 2, y + h])):
            self._pending["zone_events.csv"].append(ev.row())

    def _label(self, line: int) -> str | int:
        return self.lines[line].name or line

    def _sample(self, ft: FrameTracks) -> None:
        """Speed and length samples of the detected tracks (vehicles.py, ground.py)."""
        det = ~np.asarray(ft.coasted, dtype=bool)
        if not det.any():
            return
        states, boxes, rates = ft.states[det], ft.boxes[det], ft.size_rates[det]
        g = contact_points(states, boxes)
        g_dot = contact_velocities(states, rates)
        v = self.calibration.ground_velocity(g, g_dot)            # J_H(g) g', m/s
        speed = np.hypot(v[:, 0], v[:, 1])
        sigma = speed_sigmas(self.calibration, g, v, ft.covariances[det])
        length, k = footprint_samples(self.calibration, self.camera, boxes, v)
        m = BORDER_MARGIN * max(self.width, self.height)
        border = ((boxes[:, 0] <= m) | (boxes[:, 1] <= m)
                  | (boxes[:, 0] + boxes[:, 2] >= self.width - m)
                  | (boxes[:, 1] + boxes[:, 3] >= self.height - m))
        good = ~border & (sigma <= SPEED_SIGMA_MAX)
        for i, tid in enumerate(ft.ids[det]):
            if not np.isfinite(speed[i]):
                continue
            rec = self._record(int(tid), self.frame, self.time)
            s = rec.good if good[i] else rec.other
            s.speed.add(self.time, float(speed[i]))
            s.trace.add(self.time, float(speed[i]), self.calibration.to_world(g[i]))
            if speed[i] >= MIN_LENGTH_SPEED and np.isfinite(length[i]):
                s.length.add(float(length[i]), float(k[i]))

    def _resolve_speeds(self, tid: int, final: bool) -> None:
        """Read the speed at each of a track's crossings awaiting it (VehicleRecord.speed_at),
        once the track's good frames reach past the crossing's window (`final`: whatever the
        traces hold, NaN if nothing)."""
        waiting = False
        rec = self.vehicles[tid]
        for c in rec.crossings:
            if c[3] is None:
                c[3] = rec.speed_at(c[0], final)
                waiting = waiting or c[3] is None
        if not waiting:
            self._unresolved.discard(tid)

    def _finish(self, tid: int) -> None:
        if tid in self._unresolved:
            self._resolve_speeds(tid, final=True)
        rec = self.vehicles.pop(tid)
        self.counter.forget(tid)
        self._pending["zone_events.csv"].extend(ev.row() for ev in self.zones.end_track(tid))
        calibrated = self.calibration is not None
        if calibrated:
            cls = rec.figures()[3] or "unknown"
        else:   # the appearance class, or `all` with MOG2 alone (no class known)
            cls = (rec.looks.best() or "unknown") if self.looks else "all"
        for time, line, direction, speed in rec.crossings:
            key = self.line_keys[2 * line + DIRECTIONS.index(direction)]
            self.bins.add(time, key, cls)
            if calibrated and speed is not None and np.isfinite(speed):
                for c in (cls, "all"):
                    self.speed_bins.add(time, key, c, 3.6 * speed)
        movement = self.gates.end_track(tid)
        if movement is not None:
            self.movement_bins.add(movement.time, (movement.origin, movement.destination), cls)
        self._pending["vehicles.csv"].append(rec.row(calibrated))

    # ------------------------------------------------------------------- writing
    def line_counts(self) -> list[tuple[int, int]]:
        """(forward, backward) per line so far (for the annotated frames)."""
        return [(c["forward"], c["backward"]) for c in self.counter.counts()]

    def flush(self, final: bool = False) -> dict[str, Any]:
        """Write what became final since the last flush (all of it with `final`: the run is
        over and live tracks end here); returns summary.json's `counts`, `zones`,
        `movements`, `gates`, `bin_seconds` and `calibration` (None without one)."""
        if final:
            for tid in list(self.vehicles):
                self._finish(tid)
            end = self.time + 1.0 / self.fps
            counts, movements, speeds = (
                b.pop_final(self.time, None, run_end=end)
                for b in (self.bins, self.movement_bins, self.speed_bins))
        else:
            pending = [c[0] for rec in self.vehicles.values() for c in rec.crossings]
            first = min(pending) if pending else None
            counts = self.bins.pop_final(self.time, first)
            speeds = self.speed_bins.pop_final(self.time, first)
            movements = self.movement_bins.pop_final(self.time, self.gates.pending_from())
        self._pending["counts.csv"] += count_rows(counts, self.line_keys, self.classes)
        self._pending["movements.csv"] += count_rows(movements, self.gates.pairs(),
                                                     self.classes)
        if self.calibration is not None:
            self._pending["speeds.csv"] += speed_rows(speeds, self.line_keys, self.classes)
        for name, header in HEADERS.items():
            rows, self._pending[name] = self._pending[name], []
            if self._created:
                append_csv(self.out / name, rows)
            else:
                write_csv(self.out / name, rows, header=header)
        self._created = True
        return self.summary()

    def summary(self) -> dict[str, Any]:
        """summary.json's analytics keys as of now (counts[i] gains "name" if named)."""
        counts = self.counter.counts()
        for line, c in zip(self.lines, counts):
            if line.name:
                c["name"] = line.name
        out: dict[str, Any] = {"counts": counts, "zones": self.zones.summary(),
                               "movements": self.gates.summary(), "gates": self._gates(),
                               "bin_seconds": self.bins.bin_seconds, "calibration": None}
        if self.calibration is not None:
            cal = {"file": self.calibration.source, **self.calibration.errors()}
            if self.camera is not None:
                cal["camera_height_m"] = round(self.camera.height, 3)
                cal["focal_px"] = round(self.camera.focal, 1)
            out["calibration"] = cal
        return out

    def _gates(self) -> list[dict]:
        """summary.json `gates`: each gate's name and its line or polygon in pixels."""
        return [{"name": n, ("line" if line else "polygon"):
                 [[round(float(x), 2), round(float(y), 2)] for x, y in shape]}
                for n, shape, line in zip(self.gates.names, self.gates.shapes,
                                          self.gates.is_line)]
