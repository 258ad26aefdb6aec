"""Measurement provenance (vtrack/tracking/provenance.py): each rule on one small case, the
same detections given as whole boxes (an appearance model drew them: `seen`) and as motion
blobs, where the blob heuristics must still apply."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vtrack.app.config import AppConfig
from vtrack.boxes import centre
from vtrack.tracking.provenance import near_border, whole_boxes
from vtrack.tracking.tracker import FrameTracks, Tracker

W, H, FPS = 640, 360, 25.0


def _step(tracker: Tracker, n: int, boxes: np.ndarray, whole: bool) -> FrameTracks:
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
    return tracker.step(n, (n - 1) / FPS, centre(boxes), boxes,
                        seen=np.full(len(boxes), whole))


def _drive(tracker: Tracker, frames: int, whole: bool, size: float = 100.0) -> np.ndarray:
    """A vehicle of `size` px square driving right at 5 px/frame for `frames` frames;
    returns the box it would have on the next frame."""
    for n in range(frames):
        out = _step(tracker, n + 1, [[100.0 + 5 * n, 120.0, size, size]], whole)
    assert len(out.ids) == 1, "the vehicle is confirmed"
    return np.array([100.0 + 5 * frames, 120.0, size, size])


def _tracker() -> Tracker:
    return Tracker(AppConfig().tracker, W, H, FPS)


def test_whole_boxes_reads_seen() -> None:
    assert whole_boxes(None, 3).tolist() == [False] * 3
    assert whole_boxes(np.array([0, 2, 1]), 3).tolist() == [False, True, True]
    with pytest.raises(ValueError):
        whole_boxes(np.ones(2), 3)


def _width_after_shrink(whole: bool) -> float:
    """The track's box width the frame a detection 30 % smaller, centred where the vehicle
    is predicted, arrives (a vehicle receding fast, nothing hiding it)."""
    tracker = _tracker()
    box = _drive(tracker, 20, whole)
    out = _step(tracker, 21, [[box[0] + 15, box[1] + 15, 70.0, 70.0]], whole)
    return float(out.boxes[0, 2])


def test_a_whole_box_shrinks_the_size_at_once_a_blob_does_not() -> None:
    assert _width_after_shrink(whole=False) > 90.0   # a partial view? held by the gate
    assert _width_after_shrink(whole=True) == pytest.approx(70.0, abs=3.0)


def _pieces_after_fragments(whole: bool) -> int:
    """Detections left after the fragment stage when a second vehicle's box overlaps the
    tracked one's, its centre inside the tracked vehicle's predicted box."""
    tracker = _tracker()
    box = _drive(tracker, 20, whole)
    boxes = np.array([box, [box[0] + 80, box[1] - 10, 40.0, 60.0]])
    t = 20 / FPS
    tracker.predict(t)
    a = tracker.associator.associate(tracker.tracks, tracker.gaps, t, centre(boxes), boxes,
                                     whole=np.full(2, whole))
    return len(a.boxes)


def test_whole_boxes_are_never_joined_as_pieces_blobs_are() -> None:
    assert _pieces_after_fragments(whole=False) == 1   # joined into their union
    assert _pieces_after_fragments(whole=True) == 2


def _ids_after_a_dropped_box(whole: bool) -> int:
    """Confirmed tracks after two vehicles whose boxes overlap (a car behind another) drive
    side by side and the rear one's box is missing for one frame while its centre lies in
    the front one's box."""
    tracker = _tracker()
    for n in range(25):
        boxes = np.array([[100.0 + 5 * n, 120.0, 100.0, 100.0],
                          [130.0 + 5 * n, 110.0, 100.0, 100.0]])
        out = _step(tracker, n + 1, boxes[:1] if n == 20 else boxes, whole)
    return len(out.ids)


def test_a_whole_box_shared_for_a_frame_deletes_no_track_a_blob_does() -> None:
    assert _ids_after_a_dropped_box(whole=False) == 1   # the younger: a duplicate
    assert _ids_after_a_dropped_box(whole=True) == 2


def _tracks_after_a_vehicle_behind(whole: bool) -> int:
    """Tracks (tentative included) once a second vehicle appears with its centre inside a
    confirmed vehicle's box (a car coming out from behind a truck)."""
    tracker = _tracker()
    box = _drive(tracker, 20, whole, size=120.0)
    boxes = np.array([box, [box[0] + 70, box[1] + 30, 60.0, 40.0]])
    for n in range(21, 24):
        boxes[:, 0] += 5
        _step(tracker, n, boxes, whole)
    return len(tracker)


def test_a_whole_box_in_a_tracked_box_starts_a_track_a_blob_does_not() -> None:
    assert _tracks_after_a_vehicle_behind(whole=False) == 1   # a piece of the vehicle
    assert _tracks_after_a_vehicle_behind(whole=True) == 2


def _confirmed_crawler(whole: bool) -> bool:
    """A car crawling in behind a queue: 17 px in 7 s (under half a box scale)."""
    tracker = _tracker()
    for n in range(1, 176):
        out = _step(tracker, n, [[300.0 + 17 * (n - 1) / 175, 200.0, 40.0, 30.0]], whole)
    return len(out.ids) == 1


def test_a_crawling_vehicle_an_appearance_model_sees_is_confirmed() -> None:
    assert not _confirmed_crawler(whole=False)   # static clutter to a motion tracker
    assert _confirmed_crawler(whole=True)


def test_a_box_near_the_border_may_be_cut() -> None:
    """A drawn box's edge scatters around the border: 3 px inside it may be cut."""
    cfg = AppConfig().tracker
    boxes = np.array([[537.0, 100.0, 100.0, 60.0], [500.0, 100.0, 100.0, 60.0]])
    assert near_border(cfg, boxes, W, H).tolist() == [True, False]


def _width_near_the_border(whole: bool) -> float:
    """The track's box width the frame a detection 30 % narrower arrives 3 px short of
    the right border (a vehicle leaving the picture, its box drawn short of the border)."""
    tracker = _tracker()
    for n in range(20):
        out = _step(tracker, n + 1, [[420.0 + 5 * n, 120.0, 100.0, 100.0]], whole)
    assert len(out.ids) == 1
    out = _step(tracker, 21, [[567.0, 120.0, 70.0, 100.0]], whole)
    return float(out.boxes[0, 2])


def test_a_whole_box_near_the_border_does_not_shrink_the_size_at_once() -> None:
    assert _width_near_the_border(whole=True) > 90.0
    assert _width_near_the_border(whole=False) > 90.0


def test_a_vehicle_leaving_through_the_border_keeps_its_speed() -> None:
    """Whole boxes of a car driving out at the right border, each drawn 2 px short of the
    border (as a detector places them): the track's speed when the last box is seen is the
    car's, so its prediction follows it out instead of braking in the picture."""
    tracker = _tracker()
    speed = 10.0   # px a frame
    for n in range(1, 60):
        x0 = 400.0 + speed * n
        x1 = min(x0 + 100.0, W - 2.0)
        if x1 - x0 < 30:
            break
        _step(tracker, n, [[x0, 150.0, x1 - x0, 60.0]], whole=True)
    k = np.flatnonzero(tracker.tracks.id > 0)
    assert len(k) == 1
    assert tracker.tracks.x[k[0], 2] == pytest.approx(speed * FPS, rel=0.15)
    assert abs(tracker.tracks.x[k[0], 4]) < 0.5 * speed * FPS


def _turner(t: float) -> np.ndarray:
    """A car that drives east at 150 px/s along y = 260, turns north (left) through a
    quarter circle of radius 80 px about (300, 180) and drives north along x = 380; its
    60 x 30 box turns into 30 x 60."""
    r, v = 80.0, 150.0
    t_turn = math.pi / 2 * r / v
    if t < 1.0:
        cx, cy, f = 150.0 + v * t, 260.0, 0.0
    elif t < 1.0 + t_turn:
        a = (t - 1.0) * v / r
        cx, cy, f = 300.0 + r * math.sin(a), 180.0 + r * math.cos(a), a / (math.pi / 2)
    else:
        cx, cy, f = 380.0, 180.0 - v * (t - 1.0 - t_turn), 1.0
    w, h = 60.0 + (30.0 - 60.0) * f, 30.0 + (60.0 - 30.0) * f
    return np.array([cx - w / 2, cy - h / 2, w, h])


def _straight(t: float) -> np.ndarray:
    """A van driving west at 120 px/s along y = 200, its 90 x 44 box passing in front of
    the turner as it comes out of its turn."""
    cx = 584.0 - 120.0 * t
    return np.array([cx - 45.0, 178.0, 90.0, 44.0])


def test_a_turning_vehicle_keeps_its_id_through_a_junction() -> None:
    """Whole boxes of a car turning through a junction while a van crosses its path in
    front of it (their boxes overlap; the car's box is missing while the van hides it):
    each keeps one id from entry to exit."""
    tracker = _tracker()
    ids: dict[str, set[int]] = {"turner": set(), "straight": set()}
    for n in range(1, 71):   # until the car reaches the top of the picture
        t = (n - 1) / FPS
        a, b = _turner(t), _straight(t)
        inter = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])) * max(
            0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
        hidden = inter > 0.7 * a[2] * a[3]
        boxes = np.array([b] if hidden else [a, b])
        out = _step(tracker, n, boxes, whole=True)
        for name, true in (("straight", b),) if hidden else (("turner", a), ("straight", b)):
            if len(out.ids):   # the track nearest each vehicle, within 10 px
                gap = np.hypot(*(centre(out.boxes) - centre(true[None])).T)
                if gap.min() < 10:
                    ids[name].add(int(out.ids[np.argmin(gap)]))
    assert len(ids["turner"]) == 1 and len(ids["straight"]) == 1
    assert ids["turner"] != ids["straight"]


def _assigned_is_whole() -> list[bool]:
    """Whether the detection a confirmed track takes is a whole box, when the vehicle's
    whole box (drawn 25 % larger than its size) comes with a motion-only piece of it (a
    window, a shadow's edge) right at the predicted centre."""
    tracker = _tracker()
    box = _drive(tracker, 20, whole=True)
    whole_box = [box[0] - 12.5, box[1] - 12.5, 125.0, 125.0]
    piece = [box[0] + 35.0, box[1] + 35.0, 30.0, 30.0]
    boxes = np.array([piece, whole_box])
    t = 20 / FPS
    tracker.predict(t)
    a = tracker.associator.associate(tracker.tracks, tracker.gaps, t, centre(boxes), boxes,
                                     whole=np.array([False, True]))
    return a.whole[a.detections].tolist()


def test_a_whole_box_is_assigned_before_a_blob_nearer_the_prediction() -> None:
    assert _assigned_is_whole() == [True]
