"""The detector's changed map: the share of a box that MOG2 labelled foreground or shadow."""

from __future__ import annotations

import numpy as np
import pytest

from test_motion_detector import Scene
from vtrack.vision.changed import ChangedMap
from vtrack.vision.detect import DetectorConfig, MotionDetector
from vtrack.vision.stabilise import IDENTITY


def test_share_counts_foreground_and_shadow_labels_in_mask_pixels():
    labels = np.zeros((50, 80), np.uint8)
    labels[10:20, 10:20] = 255          # foreground
    labels[10:20, 20:30] = 127          # shadow
    m = ChangedMap(labels, 2.0, 2.0, IDENTITY)        # full resolution twice the mask's
    shares = m(np.array([[20, 20, 20, 20],              # mask [10:20, 10:20]: all foreground
                         [20, 20, 40, 20],              # foreground and shadow
                         [20, 20, 80, 20],              # half of it background
                         [100, 60, 20, 20],             # background only
                         [0, 0, 0, 0],                  # no pixels
                         [170, 10, 40, 10]]))           # beyond the right edge
    assert shares[:4] == pytest.approx([1.0, 1.0, 0.5, 0.0])
    assert np.isnan(shares[4]) and np.isnan(shares[5])
    # a box that is not on whole mask pixels is widened to them: x 21..39 is pixels 10..19
    assert m(np.array([[21.0, 21.0, 18.0, 18.0]]))[0] == 1.0


def test_share_is_read_where_the_stabiliser_put_the_frame():
    """The mask is in the stabiliser's reference pixels; boxes are in the current frame's,
    which the camera moved 6 px right: the box around the labelled block in this frame
    reads it."""
    labels = np.zeros((40, 40), np.uint8)
    labels[10:20, 10:20] = 255
    camera = np.array([[1.0, 0.0, 6.0], [0.0, 1.0, 0.0]])   # reference -> this frame
    m = ChangedMap(labels, 1.0, 1.0, camera)
    assert m(np.array([[16, 10, 10, 10]]))[0] == 1.0
    assert m(np.array([[10, 10, 10, 10]]))[0] == pytest.approx(0.4)


def test_detections_carry_mogs_labels_of_a_vehicle_and_a_shadow():
    """MOG2 labels a moving rectangle foreground and a darkened patch of the background
    shadow; the cleaned mask keeps only the rectangle, the changed map sees both."""
    scene = Scene(320, 240, [(20, 40, 40, 20, 3, 0, (40, 40, 220))])
    det = MotionDetector(DetectorConfig(min_motion=0.0, stabilise=False), 320, 240)
    shadow = (200, 150, 40, 30)
    for n in range(60):
        dets = det.detect(scene.frame(n, shadow=shadow if n == 59 else None))
    (x, y, w, h), = scene.boxes(59)
    assert len(dets) == 1                                   # the shadow is no detection
    car, patch, road = dets.changed(np.array([[x, y, w, h], shadow, [100, 180, 40, 30]]))
    assert car > 0.9
    assert patch > 0.9
    assert road < 0.05
