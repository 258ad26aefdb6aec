"""Blobs read against the tracked vehicles' predicted boxes (vision/pieces.py), cut at
their waists by the expected footprint (vision/footprint.py) and at their necks
(vision/necks.py), alone and in the detector."""

from __future__ import annotations

import cv2
import numpy as np

from vtrack.vision.blobs import BlobTests, find_blobs
from vtrack.vision.detect import DetectorConfig, MotionDetector
from vtrack.vision.footprint import cuts, split_long
from vtrack.vision.ghosts import StaticForeground
from vtrack.vision.necks import split_necks
from vtrack.vision.pieces import explained, group_pieces


def _mask(*rects: tuple[int, int, int, int], size: tuple[int, int] = (240, 320)) -> np.ndarray:
    """A 0/255 mask with the rectangles (x, y, w, h) filled."""
    m = np.zeros(size, np.uint8)
    for x, y, w, h in rects:
        m[y:y + h, x:x + w] = 255
    return m


def _detector(**kw: object) -> MotionDetector:
    det = MotionDetector(DetectorConfig(warmup_frames=5, min_motion=0.0, **kw), 320, 240)
    for _ in range(20):
        det.detect(np.full((240, 320, 3), 110, np.uint8))
    return det


def test_pieces_that_fail_alone_are_one_vehicle_in_its_predicted_box():
    """A white trailer in three pieces of 60-90 pixels, each under the noise floor of 150:
    inside the track's predicted box they are joined into one blob of 225 pixels that
    passes; the same pieces outside any predicted box, or with a passing piece among them,
    are left alone."""
    contours, stats = find_blobs(_mask((100, 100, 10, 9), (115, 100, 10, 6), (130, 100, 10, 8)))
    tests = BlobTests(150, 0.0, 1e9, 0.4, 0.0)
    ok, small = tests(stats, None)
    assert not ok.any()
    prior = np.array([[98.0, 98.0, 44.0, 14.0]])
    joined_c, joined = group_pieces(contours, stats, ok & small, prior)
    assert len(joined) == 1 and len(joined_c) == 1
    assert np.allclose(joined[0, :4], [100, 100, 40, 9])
    assert joined[0, 4] == stats[:, 4].sum()
    assert tests(joined, None)[0].all()
    # outside every predicted box, or in two of them: nothing joined
    assert len(group_pieces(contours, stats, ok, np.array([[0.0, 0.0, 50.0, 50.0]]))[1]) == 3
    two = np.array([[98.0, 98.0, 44.0, 14.0], [98.0, 98.0, 44.0, 14.0]])
    assert len(group_pieces(contours, stats, ok, two)[1]) == 3
    # one piece passes alone: the tracker's fragment stage decides
    assert len(group_pieces(contours, stats, np.array([True, False, False]), prior)[1]) == 3
    # the pieces span more than the (grown) predicted box: not one vehicle
    assert len(group_pieces(contours, stats, ok, np.array([[100.0, 98.0, 20.0, 14.0]]))[1]) == 3


def test_large_blob_explained_by_a_track_or_holding_several():
    big = np.array([[0.0, 0.0, 200.0, 150.0]])
    assert not explained(big, np.zeros((0, 4)), 320, 240).any()
    assert explained(big, np.array([[10.0, 5.0, 190.0, 140.0]]), 320, 240).all()
    # a truck leaving the picture: its predicted box beyond the image, cut before the IoU
    assert explained(big, np.array([[-150.0, 0.0, 350.0, 150.0]]), 320, 240).all()
    assert not explained(big, np.array([[50.0, 40.0, 60.0, 40.0]]), 320, 240).any()
    two = np.array([[10.0, 10.0, 80.0, 60.0], [110.0, 70.0, 80.0, 60.0]])
    assert explained(big, two, 320, 240).all()


def test_area_cap_spares_the_tracked_truck_only():
    """A truck over a quarter of the frame: dropped by the cap, kept with
    `area_cap_tracked` when its predicted box says it is a tracked vehicle, dropped when
    no track explains it."""
    img = np.full((240, 320, 3), 110, np.uint8)
    img[60:170, 40:280] = (230, 230, 230)   # 240 x 110: 34 % of the frame (under half:
    truck = np.array([[40.0, 60.0, 240.0, 110.0]])   # the gain compensation keeps it)
    assert len(_detector().detect(img, truck)) == 0
    d = _detector(area_cap_tracked=True).detect(img, truck)
    assert len(d) == 1 and np.allclose(d.boxes[0], truck[0], atol=6)
    assert len(_detector(area_cap_tracked=True).detect(img, np.array([[0.0, 0, 40, 30]]))) == 0


def test_detector_joins_a_broken_truck_in_its_predicted_box():
    img = np.full((240, 320, 3), 110, np.uint8)
    for x in (100, 122, 144):                   # three slabs of 12 x 10, 20 px apart after
        img[100:110, x:x + 10] = (230, 230, 230)   # the closing: under the floor alone
    prior = np.array([[96.0, 96.0, 62.0, 18.0]])
    assert len(_detector().detect(img, prior)) == 0
    d = _detector(group_pieces=True).detect(img, prior)
    assert len(d) == 1 and np.allclose(d.boxes[0], [100, 100, 54, 10], atol=4)


def test_cuts_at_the_waist_not_along_a_uniform_vehicle():
    two = np.r_[np.full(30, 20.0), np.full(4, 3.0), np.full(30, 20.0)]
    assert cuts(two, 14) == [30]
    assert cuts(np.full(64, 20.0), 14) == []                       # one long vehicle
    three = np.r_[np.full(20, 20.0), [2.0], np.full(20, 20.0), [2.0], np.full(20, 20.0)]
    assert cuts(three, 10) == [20, 41]
    assert cuts(two, 33) == []                    # pieces shorter than a vehicle: no cut


def _contour(mask: np.ndarray) -> np.ndarray:
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    assert len(contours) == 1
    return contours[0]


def test_platoon_is_cut_into_its_vehicles_a_truck_is_not():
    """Two cars 30 px long one behind the other, joined by a 4 px shadow strip: cut into
    two when a vehicle there is ~20 px; one truck of the same length stays whole; and the
    platoon is not cut where vehicles are as long as it."""
    platoon = _contour(_mask((50, 100, 20, 30), (58, 130, 4, 6), (50, 136, 20, 30)))
    boxes, counts = split_long(platoon, 20.0, 10)
    assert len(boxes) == 2
    order = np.argsort(boxes[:, 1])
    assert np.allclose(boxes[order[0]], [50, 100, 20, 30], atol=3)
    assert np.allclose(boxes[order[1]], [50, 136, 20, 30], atol=3)
    truck = _contour(_mask((50, 100, 20, 66)))
    assert len(split_long(truck, 20.0, 10)[0]) == 0
    assert len(split_long(platoon, 40.0, 10)[0]) == 0


def test_cars_side_by_side_split_at_their_neck_one_notched_vehicle_not():
    """Two cars 24 x 16 offset on both axes (adjacent lanes seen obliquely), touching at a
    corner: two bodies, each box its car's. A car with a notch on one side, two cars
    side by side along one axis, a single car and a blob thinner than MIN_PEAK stay whole."""
    pair = _contour(_mask((40, 100, 24, 16), (58, 84, 24, 16)))
    boxes, counts = split_necks(pair, 10)
    assert len(boxes) == 2 and counts.sum() >= 2 * 24 * 16 - 40
    order = np.argsort(boxes[:, 0])
    assert np.allclose(boxes[order[0]], [40, 100, 24, 16], atol=4)
    assert np.allclose(boxes[order[1]], [58, 84, 24, 16], atol=4)
    notched = np.zeros((240, 320), np.uint8)
    notched[100:120, 40:100] = 255
    notched[100:112, 68:72] = 0                 # a 4 px notch 60 % into a 20 px body
    assert len(split_necks(_contour(notched), 10)[0]) == 0
    in_line = _contour(_mask((40, 100, 24, 16), (60, 104, 24, 8), (80, 100, 24, 16)))
    assert len(split_necks(in_line, 10)[0]) == 0
    assert len(split_necks(_contour(_mask((40, 100, 24, 16))), 10)[0]) == 0
    assert len(split_necks(_contour(_mask((40, 100, 60, 4), (95, 96, 4, 4))), 10)[0]) == 0


def test_detector_splits_the_pinched_pair_only_with_the_switch():
    img = np.full((240, 320, 3), 110, np.uint8)
    img[100:116, 40:64] = img[84:100, 61:85] = (230, 230, 230)   # touching over 3 px
    assert len(_detector().detect(img)) == 1
    d = _detector(split_necks=True, min_pixels=100).detect(img)
    assert len(d) == 2


def test_static_foreground_is_dropped_after_its_time_not_under_held_boxes():
    """A ghost (foreground that never changes) leaves the mask after `frames` frames; a
    vehicle that keeps changing stays; a ghost under an exempt (held) box stays."""
    ghosts = StaticForeground(frames=5)
    fg = _mask((10, 10, 20, 20), (100, 100, 20, 20))
    changed = np.zeros(fg.shape, np.uint8)
    changed[100:120, 100:120] = 1                     # the second blob moves
    exempt = _mask((0, 0, 15, 40))                    # holds the left part of the first
    for n in range(1, 9):
        out = ghosts(fg, changed, exempt)
        if n <= 5:
            assert np.array_equal(out, fg)
    assert out[100:120, 100:120].all()                # moving: kept
    assert out[10:30, 10:15].all()                    # exempt: kept
    assert not out[10:30, 15:30].any()                # the ghost: dropped
    # a pixel that changes once starts again
    changed[10:30, 10:30] = 1
    assert np.array_equal(ghosts(fg, changed, exempt), fg)


def test_detector_drops_a_ghost_touching_a_moving_car():
    """A bright patch appears and stays (a ghost); a car drives along it. Without the
    static test the car's blob includes the patch until MOG2 learns it (~50 frames at
    1 / 500); with it, after the patch has stood 1 s, the car's box is its own."""
    def run(static: float) -> np.ndarray:
        det = _detector(static_seconds=static)
        for n in range(40):
            img = np.full((240, 320, 3), 110, np.uint8)
            img[100:160, 40:280] = (160, 160, 160)      # the ghost: 240 x 60
            x = 40 + 3 * n
            img[160:180, x:x + 40] = (40, 40, 200)      # a car 40 x 20 below it, touching
            d = det.detect(img)
        return d.boxes
    assert any(b[3] > 60 for b in run(0.0))                   # car and ghost: one blob
    boxes = run(1.0)
    assert len(boxes) == 1 and np.allclose(boxes[0], [40 + 3 * 39, 160, 40, 20], atol=6)
