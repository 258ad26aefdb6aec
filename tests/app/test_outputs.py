"""Output sinks: tracks.csv through the reorder buffer (sorted, appended, never rewritten
from the start), crossings.csv appended (by the traffic analytics' sink), and state that
stays flat on an endless run."""

from __future__ import annotations

import os

import numpy as np
import pytest

from vtrack.analytics.regions import CountLine
from vtrack.analytics.traffic import TrafficAnalytics
from vtrack.app.outputs import (FrameTimes, TrackedFrame, TrackEnds, TracksCsv, TrafficSink,
                                mot_lines)
from vtrack.app.track import Trails
from vtrack.fileio import GrowingFile
from vtrack.tracking.tracker import FrameTracks

LAG = 12


def _tracks(ids: list[int], rows: list[list[float]]) -> FrameTracks:
    k = len(ids)
    return FrameTracks(ids=np.array(ids, int), boxes=np.zeros((k, 4)),
                       coasted=np.zeros(k, bool), states=np.zeros((k, 6)),
                       covariances=np.zeros((k, 6, 6)), innovations=np.zeros(k),
                       rows=np.array(rows, float).reshape(-1, 7),
                       detection_of=np.zeros(k, int), size_rates=np.zeros((k, 2)))


class FakeTracker:
    """Emits rows the way the tracker does: vehicle i appears at frame 5 i and lives 30
    frames, moving right across x = 320; it is confirmed on its 6th frame (its first 6 rows
    come then) and coasts 4 frames in the middle (those rows come when it is re-acquired).
    Rows are never LAG or more frames late."""

    def step(self, frame: int) -> FrameTracks:
        ids, rows = [], []
        for i in range(max(1, (frame - 30) // 5), frame // 5 + 1):
            age = frame - 5 * i
            if not 5 <= age < 30:
                continue
            ids.append(i)
            if age == 5:
                rows += [_row(5 * i + a, i, a) for a in range(6)]
            elif age == 18:
                rows += [_row(5 * i + a, i, a) for a in range(14, 19)]
            elif not 14 <= age < 18:
                rows.append(_row(frame, i, age))
        return _tracks(ids, rows)


def _row(frame: int, tid: int, age: int) -> list[float]:
    """A 20x10 box whose centre x = 300 + 2 age crosses x = 320 at age 10."""
    return [frame, tid, 290.0 + 2.0 * age, 100.0, 20.0, 10.0, 1.0]


def _run(tmp_path, frames: int, flush_every: int, check=None):
    """Feed FakeTracker's frames to the sinks, flushing every `flush_every` frames (then
    `check(sinks)`); returns the sinks, TrackEnds, all rows emitted and the last summary."""
    tracks = TracksCsv(tmp_path / "tracks.csv", LAG)
    crossings = TrafficSink(TrafficAnalytics(tmp_path, 640, 360, 25.0,
                                             [CountLine(((320.0, 0.0), (320.0, 360.0)))]))
    times, ends, trails = FrameTimes(LAG + 1), TrackEnds(), Trails(10)
    fake, emitted = FakeTracker(), []
    for n in range(1, frames + 1):
        ft = fake.step(n)
        emitted.append(ft.rows)
        times.add(n, n / 25)
        f = TrackedFrame(n, n / 25, ft, ends.update(ft), times)
        tracks.frame(f)
        crossings.frame(f)
        trails.update(f)
        if n % flush_every == 0:
            tracks.flush()
            crossings.flush()
            if check:
                check(tracks)
    summary = {**tracks.flush(final=True), **crossings.flush(final=True)}
    return tracks, crossings, trails, ends, np.concatenate(emitted), summary


def test_tracks_csv_is_sorted_appended_and_equal_to_one_final_sort(tmp_path):
    path = tmp_path / "tracks.csv"
    seen: list[tuple[int, bytes, int]] = []

    def check(tracks):
        rows = np.loadtxt(path, delimiter=",", ndmin=2) if path.stat().st_size else \
            np.zeros((0, 10))
        assert np.array_equal(np.lexsort((rows[:, 1], rows[:, 0])), np.arange(len(rows)))
        seen.append((os.stat(path).st_ino, path.read_bytes(), tracks.file.committed))

    *_, emitted, summary = _run(tmp_path, 300, 7, check)
    final = path.read_bytes()
    assert final == b"".join(mot_lines(emitted[np.lexsort((emitted[:, 1], emitted[:, 0]))], 100))
    assert summary["tracks"] == len(np.unique(emitted[:, 1]))
    assert len({ino for ino, _, _ in seen}) == 1, "appended in place, never a rewritten copy"
    for _, data, committed in seen:   # what was committed is never rewritten
        assert final[:committed] == data[:committed]
    assert seen[-1][2] > 0.8 * len(final)   # most of it final before the end


def test_crossings_are_appended_once_per_track(tmp_path):
    _, crossings, _, _, emitted, summary = _run(tmp_path, 300, 11)
    lines = (tmp_path / "crossings.csv").read_text().splitlines()
    assert lines[0] == "frame,time_s,id,line,direction"
    ids = [int(line.split(",")[2]) for line in lines[1:]]
    assert len(ids) == len(set(ids)) == summary["counts"][0]["total"] > 40
    frame, time_s = lines[1].split(",")[:2]
    assert float(time_s) == pytest.approx(int(frame) / 25)


def test_state_stays_flat_on_a_long_run(tmp_path):
    """Thousands of vehicles pass; only the live ones and the reorder window are kept."""
    tracks, crossings, trails, ends, emitted, summary = _run(tmp_path, 6000, 250)
    vehicles = len(np.unique(emitted[:, 1]))
    assert vehicles > 1150 and summary["tracks"] == vehicles
    assert vehicles - 2 <= summary["counts"][0]["total"] <= vehicles   # the last may not yet
    assert len(tracks._open_ids) <= 7 and tracks._tail[:, 0].min() > 6000 - LAG
    counter = crossings.analytics.counter
    assert len(counter._last) <= 7 and len(counter._counted) <= 7
    assert len(crossings.analytics.vehicles) <= 7
    assert len(trails.paths) <= 7 and len(ends._active) <= 7


def test_growing_file_appends_and_replaces_only_its_tail(tmp_path):
    path = tmp_path / "out.csv"
    f = GrowingFile(path, "h\n")
    f.write([b"1\n"], [b"t1\n"])
    assert path.read_bytes() == b"h\n1\nt1\n" and f.committed == 4
    ino = os.stat(path).st_ino
    f.write([b"2\n", b"3\n"], [b"t2\nt3\n"])
    assert path.read_bytes() == b"h\n1\n2\n3\nt2\nt3\n" and f.size == 14
    f.write()
    assert path.read_bytes() == b"h\n1\n2\n3\n" and f.size == f.committed == 8
    assert os.stat(path).st_ino == ino
    f.close()


def test_frame_times_keep_a_window():
    times = FrameTimes(3)
    for n in range(1, 6):
        times.add(n, n * 0.5)
    assert times[5] == 2.5 and times[3] == 1.5
    with pytest.raises(KeyError):
        times[2]
    with pytest.raises(ValueError):
        times.add(7, 3.5)
