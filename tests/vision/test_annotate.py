"""draw_frame and save_jpeg."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vtrack.vision.annotate import draw_frame, save_jpeg, track_colour
from vtrack.vision.detect import Detections


def _frame(h: int = 240, w: int = 320) -> np.ndarray:
    return np.random.default_rng(0).integers(60, 200, (h, w, 3), dtype=np.uint8)


def _draw(image: np.ndarray, **override) -> np.ndarray:
    args = dict(
        ids=[3, 7], boxes=np.array([[20.0, 30, 40, 20], [150, 100, 50, 30]]),
        coasted=[False, True], trails={3: [(10.0, 10.0), (25.0, 30.0), (40.0, 40.0)], 7: []},
        detections=Detections(np.array([[40.0, 40]]), np.array([[20.0, 30, 40, 20]]),
                              np.array([800.0])),
        lines=[(0.0, 144.0, 320.0, 144.0)], counts=[(4, 1)], frame_index=12)
    args.update(override)
    return draw_frame(image, **args)


@pytest.mark.parametrize("shape", [(240, 320), (720, 1280)])
def test_draw_frame_returns_an_annotated_copy(shape):
    image = _frame(*shape)
    before = image.copy()
    out = _draw(image)
    assert out.shape == image.shape and out.dtype == np.uint8
    assert np.array_equal(image, before)  # the input is not modified
    assert not np.array_equal(out, image)
    x, y, h = 20, 30, 20  # the confirmed track's box edge is in its colour
    assert tuple(int(v) for v in out[y + h // 2, x]) == track_colour(3)


def test_draw_frame_with_nothing_to_draw_still_labels_the_frame():
    image = _frame()
    out = _draw(image, ids=[], boxes=np.zeros((0, 4)), coasted=[], trails={},
                detections=None, lines=[], counts=[])
    assert out.shape == image.shape
    assert not np.array_equal(out[:20, :80], image[:20, :80])  # "frame 12"
    assert np.array_equal(out[40:], image[40:])


def test_gates_and_zones_are_drawn_with_their_names():
    image = np.zeros((240, 320, 3), dtype=np.uint8)
    gate = np.array([[20.0, 200.0], [140.0, 200.0]])
    zone = np.array([[200.0, 150.0], [300.0, 150.0], [300.0, 230.0], [200.0, 230.0]])
    out = _draw(image, ids=[], boxes=np.zeros((0, 4)), coasted=[], trails={},
                detections=None, lines=[], counts=[], regions=[("north", gate), ("queue", zone)])
    assert out[200, 30].any()                 # the gate's line
    assert out[190, 300].any()                # the zone's right side, closed polygon
    assert not out[100, 100].any()            # nothing elsewhere
    named = out[185:205, 60:110]              # the gate's name at its middle
    assert (named == 0).mean() < 0.9


def test_track_colours_are_stable_and_distinct():
    assert track_colour(5) == track_colour(5)
    colours = {track_colour(i) for i in range(1, 30)}
    assert len(colours) == 29


def test_save_jpeg_is_readable_and_atomic(tmp_path):
    path = tmp_path / "frames" / "000001.jpg"
    image = cv2.resize(_frame(12, 16), (320, 240))  # smooth: JPEG keeps it within a few levels
    save_jpeg(path, image, quality=95)
    back = cv2.imread(str(path))
    assert back.shape == image.shape
    assert np.abs(back.astype(int) - image).mean() < 3
    assert [p.name for p in path.parent.iterdir()] == ["000001.jpg"]
