"""Re-identification (reidentifier.py): a vehicle lost for longer than a track coasts keeps
its id when it comes back; another vehicle does not take it; the counts keep its record open."""

import csv

import numpy as np
import pytest

from vtrack.analytics.regions import Gate
from vtrack.analytics.traffic import TrafficAnalytics
from vtrack.tracking.reidentifier import SIGNATURE_SIZE
from vtrack.tracking.tracker import FrameTracks, Tracker, TrackerConfig

W, H, FPS = 640, 360, 25.0


RED, BLUE = np.eye(SIGNATURE_SIZE)[3], np.eye(SIGNATURE_SIZE)[90]   # colour signatures


def _ids_of_rows(cfg: TrackerConfig, centre_at, frames: int, colour=RED, size=(40.0, 20.0),
                 noise: float = 0.5, seed: int = 0) -> tuple[dict[int, list[int]], list]:
    """Run scripted detections (centre_at(t) -> list of centres, or of (centre, colour,
    size) triples), boxes `size` of signature `colour` (None: no colours given); returns,
    per id, the frames of its rows, and the FrameTracks of every frame."""
    rng = np.random.default_rng(seed)
    tr = Tracker(cfg, W, H, FPS)
    frames_of: dict[int, list[int]] = {}
    out = []
    for n in range(1, frames + 1):
        t = (n - 1) / FPS
        dets = [d if len(d) == 3 else (d, colour, size) for d in centre_at(t)]
        c = np.array([d[0] for d in dets], dtype=float).reshape(-1, 2)
        c += rng.normal(0, noise, c.shape)
        wh = np.array([d[2] for d in dets], dtype=float).reshape(-1, 2)
        boxes = np.column_stack([c - wh / 2, wh])
        colours = None if colour is None else np.array([d[1] for d in dets]).reshape(
            -1, SIGNATURE_SIZE)
        ft = tr.step(n, t, c, boxes, colours=colours)
        for r in ft.rows:
            frames_of.setdefault(int(r[1]), []).append(int(r[0]))
        out.append(ft)
    return frames_of, out


def _hidden(t0: float, t1: float, y: float = 180.0, speed: float = 60.0):
    """A car driving right at `speed` px/s, hidden (no detection) between t0 and t1."""
    return lambda t: [] if t0 <= t < t1 else [(40.0 + speed * t, y)]


@pytest.mark.parametrize("hidden_for", [1.5, 2.5])
def test_a_vehicle_hidden_for_seconds_comes_back_with_its_id(hidden_for):
    """Hidden longer than max_coast_seconds (1 s): its track ends, and the track that starts
    where it reappears continues its id, held meanwhile; with reid_seconds = 0, or without
    colours, it is a new vehicle."""
    path = _hidden(2.0, 2.0 + hidden_for)
    ids, states = _ids_of_rows(TrackerConfig(), path, 175)
    assert list(ids) == [1]
    assert min(ids[1]) == 1 and max(ids[1]) == 175
    assert any(list(ft.held) == [1] for ft in states)
    assert len(states[-1].held) == 0
    off, _ = _ids_of_rows(TrackerConfig(reid_seconds=0.0), path, 175)
    assert sorted(off) == [1, 2]
    blind, _ = _ids_of_rows(TrackerConfig(), path, 175, colour=None)
    assert sorted(blind) == [1, 2]


def test_a_vehicle_lost_longer_than_reid_seconds_is_a_new_one():
    ids, _ = _ids_of_rows(TrackerConfig(reid_seconds=2.0), _hidden(2.0, 4.5), 175)
    assert sorted(ids) == [1, 2]


def test_a_vehicle_elsewhere_does_not_take_a_lost_id():
    """A car hidden at x ~ 160 px; another of its colour appears on another lane 120 px
    below while the first is remembered: it gets its own id (outside the gate)."""
    first = _hidden(2.0, 3.5)
    other = lambda t: [(200.0 + 60.0 * (t - 2.5), 300.0)] if t >= 2.5 else []  # noqa: E731
    ids, _ = _ids_of_rows(TrackerConfig(), lambda t: first(t) + other(t), 150)
    assert sorted(ids) == [1, 2]
    assert min(ids[2]) == int(np.ceil(2.5 * FPS)) + 1     # the other car, from its start


@pytest.mark.parametrize("colour, size, same", [(RED, (40.0, 20.0), True),
                                                (BLUE, (40.0, 20.0), False),
                                                (RED, (120.0, 60.0), False)])
def test_only_a_vehicle_of_its_colour_and_size_takes_a_lost_id(colour, size, same):
    """Where the lost red car is predicted, a red car of its size continues it; a blue car
    or a box three times its scale is another vehicle."""
    def path(t):
        if t < 2.0:
            return [((40.0 + 60.0 * t, 180.0), RED, (40.0, 20.0))]
        return [((40.0 + 60.0 * t, 180.0), colour, size)] if t >= 3.5 else []
    ids, _ = _ids_of_rows(TrackerConfig(), path, 150)
    assert sorted(ids) == ([1] if same else [1, 2])


def test_a_lost_id_that_another_track_continues_is_forgotten():
    """The detection comes back 0.3 s later behind the prediction (the car braked while
    hidden): a new track starts on it and confirms while the old one still coasts. When the
    old one ends, the new one continues it: its id is not held for a third track (without
    the rule it would be, for reid_seconds)."""
    def path(t):
        if t < 2.0:
            return [(40.0 + 100.0 * t, 180.0)]
        return [(216.0 + 50.0 * (t - 2.0), 180.0)] if t >= 2.3 else []
    ids, states = _ids_of_rows(TrackerConfig(), path, 125)
    assert sorted(ids) == [1, 2]
    assert all(len(ft.held) == 0 for ft in states)


def _frame(n: int, boxes: dict[int, tuple], held: tuple[int, ...] = ()) -> FrameTracks:
    ids = np.array(sorted(boxes), dtype=int)
    b = np.array([boxes[i] for i in ids], dtype=float).reshape(-1, 4)
    k = len(ids)
    states = np.column_stack([b[:, :2] + b[:, 2:] / 2, np.zeros((k, 4))])
    return FrameTracks(ids=ids, boxes=b, coasted=np.zeros(k, bool), states=states,
                       covariances=np.zeros((k, 6, 6)), innovations=np.zeros(k),
                       rows=np.column_stack([np.full(k, n), ids, b, np.ones(k)]),
                       detection_of=np.zeros(k, int), size_rates=np.zeros((k, 2)),
                       held=np.array(held, dtype=int))


@pytest.mark.parametrize("held", [True, False])
def test_a_held_id_keeps_its_record_open_through_its_gap(tmp_path, held):
    """A car passes gate w, is hidden for 40 frames (its id held: FrameTracks.held), comes
    back with its id and passes gate e: one vehicle and one w -> e movement. Were its record
    closed at the gap, the one id would be two vehicles and no movement."""
    an = TrafficAnalytics(tmp_path, W, H, FPS, bin_seconds=10.0,
                          gates=[Gate("w", line=((100, 0), (100, 360))),
                                 Gate("e", line=((540, 0), (540, 360)))])
    an.flush()
    for n in range(1, 151):
        x = 20.0 + 4.0 * n
        hidden = 60 <= n < 100
        an.add_frame(n, (n - 1) / FPS, _frame(n, {} if hidden else {1: (x, 170, 40, 20)},
                                              (1,) if hidden and held else ()))
    an.flush(final=True)
    with open(tmp_path / "vehicles.csv", newline="") as fh:
        vehicles = list(csv.DictReader(fh))
    with open(tmp_path / "movements.csv", newline="") as fh:
        moves = sum(int(r["count"]) for r in csv.DictReader(fh)
                    if (r["from"], r["to"]) == ("w", "e"))
    assert len(vehicles) == (1 if held else 2)
    assert moves == (1 if held else 0)
