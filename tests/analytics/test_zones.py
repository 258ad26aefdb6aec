"""Zones: entries, exits, dwell, occupancy, debounce of a track jittering on the border, and a
track that ends inside (empty exit); zone_events.csv and summary.json `zones`."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from vtrack.analytics.regions import Zone
from vtrack.analytics.traffic import TrafficAnalytics
from vtrack.analytics.zones import ZoneCounter
from vtrack.tracking.tracker import FrameTracks

FPS = 25.0
SQUARE = np.array([[100.0, 100.0], [200.0, 100.0], [200.0, 200.0], [100.0, 200.0]])


def _counter(debounce: float = 0.2) -> ZoneCounter:
    return ZoneCounter(["bay"], [SQUARE], [debounce])


def _walk(zc: ZoneCounter, tid: int, ys, start: int = 1, x: float = 150.0) -> list:
    """Ground points (x, y) one per frame; returns the finished stays."""
    out = []
    for k, y in enumerate(ys):
        n = start + k
        out += zc.add(tid, n, (n - 1) / FPS, np.array([x, y]))
    return out


def test_enter_exit_and_dwell():
    zc = _counter()
    ys = np.arange(52.5, 260.0, 5.0)            # 5 px per frame through y = 100..200
    events = _walk(zc, 1, ys)
    assert len(events) == 1
    ev = events[0]
    first_in = 1 + int(np.argmax(ys > 100))     # frames are 1-based
    first_out = 1 + int(np.argmax(ys > 200))
    assert (ev.enter_frame, ev.exit_frame) == (first_in, first_out)
    assert ev.dwell_s == pytest.approx((first_out - first_in) / FPS)
    assert zc.summary() == [{"name": "bay", "entries": 1, "max_occupancy": 1,
                             "mean_dwell_s": round(ev.dwell_s, 4),
                             "polygon": SQUARE.tolist()}]


def test_jitter_on_the_border_is_one_stay():
    """A ground point swinging +-3 px around the zone's edge for a second, then going in:
    one entry, dated from the first frame of the lasting stay."""
    zc = _counter()
    jitter = [100 - 3 * (-1) ** k for k in range(25)]          # 97, 103, 97, ...
    ys = jitter + [110.0] * 30 + [250.0] * 10
    events = _walk(zc, 1, ys)
    assert len(events) == 1
    assert events[0].enter_frame == 26                         # the first frame of 110
    assert zc.summary()[0]["entries"] == 1
    plain = _counter(debounce=0.0)
    assert len(_walk(plain, 1, ys)) > 5                        # without the debounce


def test_a_track_ending_inside_has_no_exit_and_occupancy_counts_overlaps():
    zc = _counter()
    _walk(zc, 1, [150.0] * 20)                                 # parked inside from frame 1
    _walk(zc, 2, [50.0] * 5 + [150.0] * 20, start=6)           # joins at frame 11
    assert zc.summary()[0]["max_occupancy"] == 2
    open_1 = zc.end_track(1)
    assert len(open_1) == 1 and open_1[0].exit_frame is None
    assert open_1[0].enter_frame == 1
    assert open_1[0].dwell_s == pytest.approx(19 / FPS)         # up to its last row
    assert open_1[0].row()[3] == ""
    assert zc.end_track(2)[0].enter_frame == 11
    assert zc.summary()[0]["entries"] == 2


def _frame(n: int, boxes: dict[int, tuple]) -> FrameTracks:
    ids = np.array(sorted(boxes), dtype=int)
    b = np.array([boxes[i] for i in ids], dtype=float).reshape(-1, 4)
    k = len(ids)
    states = np.column_stack([b[:, :2] + b[:, 2:] / 2, np.zeros((k, 4))])
    rows = np.column_stack([np.full(k, n), ids, b, np.ones(k)])
    return FrameTracks(ids=ids, boxes=b, coasted=np.zeros(k, bool), states=states,
                       covariances=np.zeros((k, 6, 6)), innovations=np.zeros(k), rows=rows,
                       detection_of=np.zeros(k, int), size_rates=np.zeros((k, 2)))


def test_zone_events_file_and_summary(tmp_path):
    """Through TrafficAnalytics: the ground point (bottom centre of the box) decides; a zone
    in fractions of the image; a vehicle still inside at the end has an empty exit."""
    zone = Zone("stop-line", ((0.25, 0.5), (0.75, 0.5), (0.75, 0.75), (0.25, 0.75)), "fraction")
    an = TrafficAnalytics(tmp_path, 400, 200, FPS, zones=[zone])   # zone y 100..150 px
    an.flush()
    for n in range(1, 61):
        boxes = {1: (180, 41 + 3 * n, 40, 30)}        # bottom y = 71 + 3n: in at n = 10..26
        if n >= 30:
            boxes[2] = (150, 90, 40, 30)              # bottom at 120: inside from frame 30
        an.add_frame(n, (n - 1) / FPS, _frame(n, boxes))
    summary = an.flush(final=True)
    with open(tmp_path / "zone_events.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["id", "zone", "enter_frame", "exit_frame", "enter_time_s", "dwell_s"]
    by_id = {int(r[0]): r for r in rows[1:]}
    assert by_id[1][1:4] == ["stop-line", "10", "27"]
    assert float(by_id[1][5]) == pytest.approx(17 / FPS)
    assert by_id[2][2:4] == ["30", ""]
    assert float(by_id[2][5]) == pytest.approx(30 / FPS)        # frames 30..60
    z = summary["zones"][0]
    assert z["name"] == "stop-line" and z["entries"] == 2 and z["max_occupancy"] == 1
    assert z["mean_dwell_s"] == pytest.approx(np.mean([17 / FPS, 30 / FPS]), abs=1e-4)
