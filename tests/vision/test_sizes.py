"""The noise floor in vehicle units (vision/sizes.py)."""

from __future__ import annotations

import numpy as np
import pytest

from vtrack.vision.sizes import MIN_BOXES, REFIT_EVERY, SizeFloor, fit_size


def _boxes(rng: np.random.Generator, n: int) -> np.ndarray:
    """Boxes of a perspective view 640x360: side s = 4 + 60 y / 360 (+-10 % per vehicle)."""
    x, y = rng.uniform(100, 500, n), rng.uniform(20, 340, n)
    s = (4 + 60 * y / 360) * rng.uniform(0.9, 1.1, n)
    return np.column_stack([x - s / 2, y - s / 2, s, s])


def test_fit_recovers_a_linear_size_field_despite_merged_boxes():
    rng = np.random.default_rng(0)
    b = _boxes(rng, 600)
    b[:60, 2:] *= 2.5                                   # a tenth are merges: much larger
    c = b[:, :2] + b[:, 2:] / 2
    coef = fit_size(np.column_stack([c / [640, 360], np.sqrt(b[:, 2] * b[:, 3])]))
    assert np.allclose(coef, [4.0, 0.0, 60.0], atol=[1.5, 1.5, 3.0])


def test_floor_is_min_pixels_until_learnt_then_falls_where_vehicles_are_small():
    rng = np.random.default_rng(1)
    floor = SizeFloor(640, 360, share=0.3, min_far=20, min_pixels=150)
    far, near = np.array([[320.0, 10.0]]), np.array([[320.0, 330.0]])
    assert floor(far)[0] == 150
    frames = 0
    while floor.coef is None:
        floor.add(_boxes(rng, 10))
        frames += 1
    assert frames >= MIN_BOXES // 10 and frames % REFIT_EVERY == 0
    assert floor(near)[0] == 150                      # 0.3 * 59^2 > 150: min_pixels
    assert floor(far)[0] == 20                        # 0.3 * 5.7^2 = 10: the noise floor
    assert abs(floor(np.array([[320.0, 30.0]]))[0] - 0.3 * 9 ** 2) < 4   # s = 9 there


def test_least_side_drops_slivers_thinner_than_a_share_of_a_vehicle():
    from vtrack.vision.blobs import BlobTests

    floor = SizeFloor(640, 360, share=0.3, min_far=20, min_pixels=150,
                      coef=np.array([4.0, 0.0, 60.0]), side_share=0.4)
    floor.add(np.array([[0.0, 0.0, 300.0, 300.0]] * MIN_BOXES))   # a fixed field
    assert np.array_equal(floor.coef, [4.0, 0.0, 60.0])
    centres = np.array([[320.0, 180.0]])               # s = 34 there: sides >= 13.6
    assert floor.least_side(centres)[0] == pytest.approx(0.4 * 34.0)
    assert SizeFloor(640, 360, 0.3, 20, 150).least_side(centres)[0] == 0   # before a fit
    tests = BlobTests(150, 0.0, 1e9, 0.0, 0.0, least_side=floor.least_side)
    # x, y, w, h, pixel count, all centred at (320, 180): a car, a sliver, a thin post
    stats = np.array([[305, 165, 30, 30, 700], [290, 177, 60, 6, 300],
                      [314, 150, 12, 60, 600]], float)
    ok, _ = tests(stats, None)
    assert ok.tolist() == [True, False, False]
