"""Tracker behaviour on scripted detections (no video): identity through gaps, coasting
rows, confirmation back-fill, merged blobs, finite-difference measurement maths."""

import numpy as np
import pytest

from vtrack.estimation.kalman import kf_update
from vtrack.tracking.filter_bank import CentreColumns
from vtrack.tracking.lifecycle import Initiator
from vtrack.tracking.measurements import (HistoryColumns, difference_operator,
                                          finite_difference_measurement)
from vtrack.tracking.reidentifier import ReidColumns
from vtrack.tracking.reporter import leaves_on_its_way
from vtrack.tracking.sizes import Sizes
from vtrack.tracking.table import TrackTable
from vtrack.tracking.tracker import Tracker, TrackerConfig

W, H, FPS = 640, 360, 25.0


class Row:
    def __init__(self, frame, tid, x, y, w, h, conf):
        self.frame, self.id, self.box, self.conf = int(frame), int(tid), np.array([x, y, w, h]), conf


def _run_boxes(boxes_at, frames, cfg=None, noise=0.5, seed=0):
    """boxes_at(t) -> list of (x, y, w, h) detections; returns the FrameTracks per frame."""
    rng = np.random.default_rng(seed)
    tr = Tracker(cfg or TrackerConfig(), W, H)
    out = []
    for n in range(1, frames + 1):
        t = (n - 1) / FPS
        b = np.array(boxes_at(t), dtype=float).reshape(-1, 4)
        b[:, :2] += rng.normal(0, noise, (len(b), 2))
        out.append(tr.step(n, t, b[:, :2] + b[:, 2:] / 2, b))
    return out


def _run(paths, gaps=(), frames=300, cfg=None, noise=1.0, seed=0):
    """paths: list of f(t) -> (x, y) or None (40 x 20 boxes centred there); gaps: frames
    where no detection is produced. Returns the rows and the FrameTracks per frame."""
    def boxes_at(t):
        if round(t * FPS) + 1 in gaps:
            return []
        centres = [p for f in paths if (p := f(t)) is not None]
        return [(x - 20, y - 10, 40, 20) for x, y in centres]

    states = _run_boxes(boxes_at, frames, cfg, noise, seed)
    return [Row(*r) for s in states for r in s.rows], states


def _accelerating(t):
    return (20 + 100 * t + 0.5 * 30 * t**2, 180.0) if t < 5.5 else None


def test_gap_keeps_identity_and_coasted_rows_have_low_conf():
    gaps = set(range(90, 98))  # 8 lost frames, as vehicle 8 of seed 001 (frames 190-197)
    rows, _ = _run([_accelerating], gaps=gaps, frames=130)
    ids = {r.id for r in rows}
    assert ids == {1}
    by_frame = {r.frame: r for r in rows}
    assert all(by_frame[n].conf < 1.0 for n in gaps)
    assert all(0 < by_frame[n].conf for n in gaps)
    assert by_frame[89].conf == 1.0 and by_frame[98].conf == 1.0
    # the coasted prediction stays close to the truth (quadratic error growth is small here)
    err = max(abs(by_frame[n].box[0] + by_frame[n].box[2] / 2 - _accelerating((n - 1) / FPS)[0])
              for n in gaps)
    assert err < 6.0


def test_confirmation_backfills_rows_from_first_detection():
    rows, _ = _run([_accelerating], frames=20)
    assert min(r.frame for r in rows) == 1
    assert sorted(r.frame for r in rows) == list(range(1, 21))


def test_single_spurious_detection_never_becomes_a_track():
    flash = lambda t: (300.0, 100.0) if abs(t - 1.0) < 0.03 else None  # noqa: E731
    rows, _ = _run([flash], frames=60)
    assert rows == []


def test_two_crossing_vehicles_keep_their_ids():
    a = lambda t: (30 + 110 * t, 150 + 5 * t)  # noqa: E731
    b = lambda t: (600 - 110 * t, 170 - 5 * t)  # noqa: E731
    rows, _ = _run([a, b], frames=125, noise=0.5)
    ids = sorted({r.id for r in rows})
    assert ids == [1, 2]
    first = {i: min((r for r in rows if r.id == i), key=lambda r: r.frame) for i in ids}
    last = {i: max((r for r in rows if r.id == i), key=lambda r: r.frame) for i in ids}
    for i in ids:  # each id ends on the side opposite to where it started
        x0 = first[i].box[0] + first[i].box[2] / 2
        x1 = last[i].box[0] + last[i].box[2] / 2
        assert abs(x1 - x0) > 400


def test_track_deleted_when_it_leaves_the_image():
    exit_right = lambda t: (500 + 200 * t, 100.0) if 500 + 200 * t < W - 5 else None  # noqa
    _, states = _run([exit_right], frames=60)
    assert len(states[-1].ids) == 0


def test_velocity_estimate_converges():
    cfg = TrackerConfig(detection_sigma=1.5)
    _, states = _run([_accelerating], frames=88, noise=1.5, cfg=cfg)
    err = [s.states[0, 2] - (100 + 30 * (n - 1) / FPS) for n, s in enumerate(states, 1)
           if n > 30]
    # measured: ~8 px/s RMSE at q_j = 1e4 (the FD velocity 'measurement' alone has
    # std sqrt(2) * 1.5 / 0.04 = 53 px/s)
    assert np.sqrt(np.mean(np.square(err))) < 15.0


@pytest.mark.parametrize("measurement", ["finite-difference", "position"])
def test_both_measurement_options_track(measurement):
    rows, _ = _run([_accelerating], frames=100, cfg=TrackerConfig(measurement=measurement))
    assert {r.id for r in rows} == {1}


def test_difference_operator_equal_spacing_matches_seed_matrix():
    dt = 0.04
    D = difference_operator(np.array(dt), np.array(dt))
    R = D @ D.T
    expected = np.array([[1, 1 / dt, 1 / dt**2],
                         [1 / dt, 2 / dt**2, 3 / dt**3],
                         [1 / dt**2, 3 / dt**3, 6 / dt**4]])
    np.testing.assert_allclose(R, expected, rtol=1e-12)


def test_finite_differences_exact_for_quadratic_motion_unequal_spacing():
    t = np.array([[0.30, 0.12, 0.04]])  # newest first, unequal gaps (after a loss)
    p = lambda s: np.stack([3 + 2 * s + 0.5 * 7 * s**2, -1 + 4 * s], -1)  # noqa: E731
    z, R, mask = finite_difference_measurement(p(t)[..., :], t, np.array([3]), 1.0)
    assert mask.all()
    np.testing.assert_allclose(z[0, [0, 1]], p(t[0, 0]))
    np.testing.assert_allclose(z[0, 4], 7.0, atol=1e-9)           # ax exact
    np.testing.assert_allclose(z[0, 5], 0.0, atol=1e-9)
    # R = sigma^2 D D' is symmetric positive definite
    assert np.linalg.eigvalsh(R[0]).min() > 0


def test_masked_rows_do_not_change_the_update():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(6, 6))
    P = A @ A.T + np.eye(6)
    x = rng.normal(size=6)
    z = rng.normal(size=6)
    Rfull = np.diag(rng.uniform(0.5, 2, 6))
    mask = np.array([True, True, True, True, False, False])
    x1, P1, _ = kf_update(x, P, z - x, np.eye(6), Rfull, mask=mask)
    x2, P2, _ = kf_update(x, P, (z - x)[:4], np.eye(6)[:4], Rfull[:4, :4])
    np.testing.assert_allclose(x1, x2, atol=1e-12)
    np.testing.assert_allclose(P1, P2, atol=1e-12)


@pytest.mark.parametrize("kind", ["ankf1", "ankf2", "fuzzy-r", "fuzzy-q", "siim-ekf"])
def test_adaptive_kinds_as_the_per_vehicle_filter(kind):
    """Each adaptive kind of the core runs per track, bridges the lost frames with one id and
    keeps the state arrays equal to its filter objects."""
    gaps = set(range(60, 66))
    rows, states = _run([_accelerating], gaps=gaps, frames=90, cfg=TrackerConfig(filter=kind))
    assert {r.id for r in rows} == {1}
    assert sorted(r.frame for r in rows) == list(range(1, 91))
    err = [abs(r.box[0] + r.box[2] / 2 - _accelerating((r.frame - 1) / FPS)[0]) for r in rows
           if r.frame > 20]
    assert max(err) < 8.0


def test_unknown_per_vehicle_filter_is_rejected():
    with pytest.raises(ValueError, match="tracker.filter"):
        Tracker(TrackerConfig(filter="ukf"), W, H)


def _side_by_side(t):
    """Two cars in adjacent lanes driving together: one merged blob until t = 1.6 s (as far
    from the camera), then two detections with a gap between the lanes."""
    x = 40 + 120 * t
    if t < 1.6:
        return [(x, 160, 40, 50)]
    return [(x, 160, 40, 20), (x, 190, 40, 20)]


def test_vehicles_of_one_blob_get_their_own_tracks_when_it_comes_apart():
    states = _run_boxes(_side_by_side, frames=110)
    last = states[-1]
    assert len(last.ids) == 2
    ys = sorted(last.boxes[:, 1] + last.boxes[:, 3] / 2)
    assert ys == pytest.approx([170, 200], abs=3)
    assert np.all(last.boxes[:, 3] < 30)  # neither box still spans both lanes


def _truck_overtakes_car(t):
    """A 300 x 200 truck overtakes a 40 x 30 car in the next lane; from t = 1.08 s the
    detector gives one blob (their union), from 1.23 s the car's box lies mostly inside the
    truck's (mg70_motorway_trucks: a car beside an articulated truck)."""
    car = (460 + 20 * t, 135, 40, 30)
    truck = (20 + 150 * t, 100, 300, 200)
    if truck[0] + truck[2] < car[0]:
        return [car, truck]   # the car first: its track is the older one
    x1 = max(truck[0] + truck[2], car[0] + car[2])
    return [(truck[0], 100, x1 - truck[0], 200)]


def test_large_vehicle_keeps_the_blob_a_small_one_lies_in():
    """The blob is the truck's: the car's (older) track neither takes it nor has the
    truck's track deleted as its duplicate."""
    states = _run_boxes(_truck_overtakes_car, frames=50, noise=0.3)
    apart = states[24]                     # t = 0.96 s: both confirmed, apart
    assert len(apart.ids) == 2
    truck_id = apart.ids[np.argmax(apart.boxes[:, 2])]
    car_id = apart.ids[np.argmin(apart.boxes[:, 2])]
    last = states[-1]
    assert truck_id in last.ids
    assert np.all(last.boxes[last.ids == truck_id, 2:] > [250, 170])
    assert np.all(last.boxes[last.ids == car_id, 2] < 100)


def _behind_a_pole(t):
    """One car (60 px long) passing behind a static pole at x in [300, 312]: while it
    overlaps the pole it is detected as two pieces with a gap that does not move."""
    x0, x1 = 100 + 120 * t, 160 + 120 * t
    pieces = [(a, b) for a, b in ((x0, min(x1, 300)), (max(x0, 312), x1)) if b - a >= 2]
    return [(a, 170, b - a, 20) for a, b in pieces]


def _road(boxes):
    """A changed map (vision/changed.py) that sees road everywhere: no pixel changed."""
    return np.zeros(len(boxes))


def _body(boxes):
    """A changed map that sees every pixel changed: MOG2 labelled the gap foreground or
    shadow, the body of one vehicle."""
    return np.ones(len(boxes))


def _run_changed(boxes_at, frames, changed, noise=0.3, seed=0):
    """As _run_boxes, with the detector's changed map given to the tracker."""
    rng = np.random.default_rng(seed)
    tr = Tracker(TrackerConfig(), W, H)
    out = []
    for n in range(1, frames + 1):
        t = (n - 1) / FPS
        b = np.array(boxes_at(t), dtype=float).reshape(-1, 4)
        b[:, :2] += rng.normal(0, noise, (len(b), 2))
        out.append(tr.step(n, t, b[:, :2] + b[:, 2:] / 2, b, changed=changed))
    return out


@pytest.mark.parametrize("changed", [None, _road])
def test_occluder_pieces_stay_one_vehicle(changed):
    """The pole is background, so with a changed map its gap reads as road; it stays put
    while the car moves, which is what an occluder does."""
    states = _run_changed(_behind_a_pole, 75, changed, noise=0.5)
    ids = set().union(*(s.ids.tolist() for s in states))
    assert ids == {1}
    assert len(states[-1].ids) == 1


def _tandem(t):
    """Two 40 x 20 cars one behind the other at 120 px/s, 8 px apart: one blob until
    t = 1.0 s (frame 26), then two pieces."""
    front = 200 + 120 * t
    if t < 1.0:
        return [(front - 48, 170, 88, 20)]
    return [(front - 48, 170, 40, 20), (front, 170, 40, 20)]


def test_a_gap_of_road_that_moves_with_the_track_splits_it_on_its_second_frame():
    """Without the changed map the gap's motion must add up to `split_evidence` box scales
    (three frames here); a gap that MOG2 left unlabelled is road between two vehicles, and
    on its second frame it has moved with them."""
    first = 26
    width = {}
    for name, changed in (("motion", None), ("road", _road)):
        states = _run_changed(_tandem, 60, changed)
        width[name] = [float(states[n - 1].boxes[0, 2]) for n in range(first, first + 4)]
        assert len(states[-1].ids) == 2 and np.all(states[-1].boxes[:, 2] < 50)
    assert width["road"][1] < 50 < width["motion"][1]     # split at frame 27 ...
    assert width["motion"][3] < 50                        # ... and by the motion at 29


def test_a_gap_of_body_is_one_vehicle_however_it_moves():
    """Two pieces whose gap moves with the track are split by the gap's motion alone; where
    MOG2 labelled the gap foreground or shadow, it is the body of one vehicle seen in two
    pieces (a dark car's middle), and the track stays whole."""
    assert len(_run_changed(_tandem, 60, None)[-1].ids) == 2
    states = _run_changed(_tandem, 60, _body)
    assert set().union(*(s.ids.tolist() for s in states)) == {1}
    assert states[-1].boxes[0, 2] == pytest.approx(88, abs=3)


def _tandem_flickering(t):
    """Two cars in tandem whose boxes overlap on both axes (no gap to read), seen as two
    pieces on two frames in three and as one blob on the third (a detector flickering
    between two vehicles and their union, as on bgslibrary's highway)."""
    front = 200 + 120 * t
    if t < 1.0 or round(t * FPS) % 3 == 2:
        return [(front - 30, 170, 70, 26)]
    return [(front - 30, 176, 40, 20), (front, 170, 40, 20)]


def test_the_gap_record_survives_a_merged_frame_with_the_changed_map():
    """Each merged frame forgets the gap, so on its own the evidence never adds up and the
    pair stays one track. With the changed map the record is held through one merged frame
    (`split_hold_seconds`) while no frame showed the gap changed, and the second car gets
    its own track."""
    without = _run_changed(_tandem_flickering, 75, None)
    assert set().union(*(s.ids.tolist() for s in without)) == {1}
    held = _run_changed(_tandem_flickering, 75, _road)
    assert max(len(s.ids) for s in held) == 2


def _creeping_in_pieces(t):
    """A 40 x 20 car creeping at 20 px/s (a queue moving up), seen whole but for 0.3 s from
    t = 1.0 s, when its even paint shows as two pieces with an 8 px gap in its middle: by
    then it has moved 20 px, half its length."""
    x = 200 + 20 * t
    if 1.0 <= t < 1.3:
        return [(x, 170, 16, 20), (x + 24, 170, 16, 20)]
    return [(x, 170, 40, 20)]


def test_a_gap_in_a_vehicle_that_has_not_moved_its_length_is_not_read():
    """MOG2's labels inside a vehicle that has not yet moved its own length say nothing
    about body or road: the road it covers may be road it stood on (learnt into the
    background with it), and a slow vehicle's even paint looks unchanged. The gap (which
    moves with the car, being part of it) is then judged by its motion alone, which needs
    `split_evidence` box scales of travel: the pieces join and the car keeps one track."""
    states = _run_changed(_creeping_in_pieces, 50, _road)
    assert set().union(*(s.ids.tolist() for s in states)) == {1}
    assert states[-1].boxes[0, 2] == pytest.approx(40, abs=3)


@pytest.mark.parametrize("pieces,held", [
    ([(0, 0, 26, 30), (34, 0, 26, 30)], True),    # front and back, road between them
    ([(0, 0, 60, 30), (40, 4, 14, 8)], False),    # a piece within the other's box
])
def test_only_a_gap_between_pieces_is_a_record_to_hold(pieces, held):
    """The record of a gap between two pieces is held through a merged frame only while it
    may be road between two vehicles; a piece lying within the other's box is a part of
    it (a car's windows in the box of its body and shadow): no gap, nothing to hold."""
    tr = Tracker(TrackerConfig(), W, H)
    for n in range(1, 32):                 # a 60 x 30 car at 120 px/s, confirmed
        t = (n - 1) / FPS
        box = np.array([[100 + 120 * t, 170, 60, 30]])
        tr.step(n, t, box[:, :2] + box[:, 2:] / 2, box, changed=_road)
    t = 31 / FPS
    b = np.array(pieces, dtype=float) + [100 + 120 * t, 170, 0, 0]
    tr.step(32, t, b[:, :2] + b[:, 2:] / 2, b, changed=_road)
    assert tr.gaps.gap_t[0] == pytest.approx(t)         # the pieces were recorded ...
    assert bool(tr.gaps.gap_road[0]) is held            # ... as a gap that may be road


@pytest.mark.parametrize("confirm_motion,expect_track", [(0.3, False), (0.0, True)])
def test_blob_that_never_moves_is_not_confirmed(confirm_motion, expect_track):
    """Swaying leaves: a blob detected in every frame, jittering but going nowhere."""
    leaves = lambda t: (200 + 3 * np.sin(9 * t), 120 + 2 * np.cos(7 * t))  # noqa: E731
    rows, _ = _run([leaves], frames=200, cfg=TrackerConfig(confirm_motion=confirm_motion))
    assert bool(rows) == expect_track


def test_tentative_track_keeps_a_detection_that_jumps_inside_its_box():
    """The visible part of a vehicle jumps 16 px sideways, out of the gate but inside the
    box (part of it goes behind a tree), while its track is still tentative: the track takes
    it, no second track starts."""
    tr = Tracker(TrackerConfig(), W, H)
    for n in range(1, 6):
        t = (n - 1) / FPS
        x = 100 + 100 * t
        y = 180.0 if n < 5 else 196.0
        box = np.array([[x - 50, y - 20, 100, 40]])
        tr.step(n, t, box[:, :2] + box[:, 2:] / 2, box)
        assert len(tr) == 1
    assert tr.tracks.hitmask[0] & 1                     # detected on the last frame


def _rows_of_vehicles_leaving():
    """The rows of 80 x 24 vehicles driving out of the right edge at 21 speeds; detections
    (clipped to the image) stop when less than half is visible and the tracks coast out."""
    rows = []
    for k, speed in enumerate(np.linspace(60, 260, 21)):
        def leaving(t, speed=speed):
            x0 = 400 + speed * t
            x1 = min(x0 + 80, W)
            return [(x0, 150, x1 - x0, 24)] if x1 - x0 >= 40 else []
        states = _run_boxes(leaving, frames=60, seed=k)
        rows.extend(r for s in states for r in s.rows)
    return np.array(rows)


def test_rows_of_a_vehicle_leaving_the_image_have_visible_boxes():
    """No row of a vehicle leaving the image may carry an empty box (eval and INTERFACE
    require w, h > 0)."""
    rows = _rows_of_vehicles_leaving()
    assert len(rows) > 0
    assert np.all(rows[:, 4] >= 1.0) and np.all(rows[:, 5] >= 1.0)


def test_coasted_row_mostly_out_of_the_image_is_not_reported():
    """A coasted row is written while at least a quarter of its predicted box is in the
    image: beyond that the clipped box is a sliver placed by the prediction alone (none of
    the suite's 70 such rows that are scored matched a vehicle). The tail before that is
    still reported, on the vehicle's way."""
    rows = _rows_of_vehicles_leaving()
    coasted = rows[rows[:, 6] < 1.0]
    assert len(coasted) >= 21                       # every vehicle's tail is kept in part
    assert coasted[:, 4].min() >= 0.25 * 80 - 2.0   # no sliver: a quarter of the box, or more


def test_coasted_rows_are_reported_only_when_the_reacquisition_confirms_them():
    """Two vehicles, each unseen for 8 frames. One drives on as predicted: its gap is filled
    with coasted rows. The other halves its speed while unseen: the detection that
    re-acquires it (same id) is 19 px behind the prediction (IoU 0.36 for its 40 px box),
    refutes the coasted rows, and none are reported for its gap."""
    gaps = set(range(60, 68))

    def on(t):
        return (40 + 120 * t, 100.0)

    def slowing(t):
        n = round(t * FPS) + 1
        return (40 + 120 * (min(n, 60) - 1) / FPS + 60 * max(n - 60, 0) / FPS, 250.0)

    rows, _ = _run([on, slowing], gaps=gaps, frames=90, noise=0.3)
    by_lane = {lane: {r.frame: r for r in rows if abs(r.box[1] + 10 - lane) < 20}
               for lane in (100, 250)}
    assert {r.id for r in by_lane[100].values()} == {1}
    assert {r.id for r in by_lane[250].values()} == {2}
    assert all(n in by_lane[100] and by_lane[100][n].conf < 1 for n in gaps)
    assert not any(n in by_lane[250] for n in gaps)
    assert by_lane[250][59].conf == 1.0 and by_lane[250][68].conf == 1.0


def test_coasted_rows_are_smoothed_once_the_vehicle_is_reacquired():
    """A vehicle at 150 px/s brakes at 100 px/s^2 while unseen for 10 frames; the
    re-acquisition is on course (about 7 px behind the straight prediction: IoU 0.7). Smoothed
    (RTS), the gap's rows follow the braking; unsmoothed, they are the prediction, whose
    error grows to the re-acquisition's offset."""
    gaps = set(range(60, 70))
    t_brake = 59 / FPS

    def braking(t):
        dt = max(t - t_brake, 0.0)
        return (40 + 150 * t - 0.5 * 100 * dt**2, 180.0)

    def gap_errors(smooth):
        rows, _ = _run([braking], gaps=gaps, frames=90, noise=0.3,
                       cfg=TrackerConfig(smooth_coasted=smooth))
        by_frame = {r.frame: r for r in rows}
        assert {r.id for r in rows} == {1} and all(n in by_frame for n in gaps)
        return np.array([by_frame[n].box[0] + 20 - braking((n - 1) / FPS)[0] for n in gaps])

    smoothed, predicted = gap_errors(True), gap_errors(False)
    assert np.abs(predicted).max() > 3.0           # the prediction overshoots the braking
    assert np.abs(smoothed).max() < 0.5 * np.abs(predicted).max()
    assert np.abs(smoothed).mean() < 0.5 * np.abs(predicted).mean()


def test_detected_rows_show_the_whole_vehicle_detection_box():
    """An approaching vehicle's box grows 3 % a frame; the filtered size lags such growth,
    a detected row shows the detection's box."""
    def growing(t):
        s = 1.03 ** (t * FPS)
        w, h = 30 * s, 16 * s
        x, y = 100 + 60 * t, 100 + 20 * t
        return [(x - w / 2, y - h / 2, w, h)]

    states = _run_boxes(growing, frames=40, noise=0.0)
    rows = np.array([r for s in states for r in s.rows])
    assert len(rows) > 30
    truth = np.array([growing((f - 1) / FPS)[0] for f in rows[:, 0]])
    assert np.allclose(rows[:, 2:6], truth, atol=1e-6)


@pytest.mark.parametrize("moved,velocity,reported", [
    ((400, 0), (200, 0), True),      # coasts out of the right edge the way it drove
    ((400, 0), (130, 110), True),    # 40 degrees off its way: still on it
    ((400, 0), (60, 200), False),    # a jump of its last boxes turned it down: not its way
    ((10, 0), (200, 0), False),      # never went anywhere (a flicker at the border)
])
def test_coasted_tail_out_of_the_image_is_reported_only_on_the_vehicles_way(
        moved, velocity, reported):
    """A track that coasts out of the image has no detection to confirm its tail: the tail
    is reported when the track's velocity points along its net displacement since its first
    detection (within 45 degrees, over at least one box scale), as a vehicle lost before the
    edge keeps going; junk that veered off (a merged or piecewise blob) is not."""
    first = np.array([[100.0, 170.0, 40.0, 20.0]])
    x0 = np.array([[120.0 + moved[0], 180.0 + moved[1], *velocity, 0.0, 0.0]])
    table = TrackTable(CentreColumns(x0, np.eye(6)[None]), HistoryColumns.new(1, 0.0),
                       Sizes(TrackerConfig(), W, H).new(first), Initiator(8).new(first),
                       ReidColumns.new(1, 0.0))
    table.last_box = table.origin + np.array([*moved, *moved], dtype=float)
    assert leaves_on_its_way(table, 0) is reported
