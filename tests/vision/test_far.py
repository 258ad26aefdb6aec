"""The far band, searched by MOG2 at full resolution (vision/far.py)."""

from __future__ import annotations

import numpy as np
import pytest

from vtrack.vision.detect import DetectorConfig, MotionDetector
from vtrack.vision.far import (FAR_LAG, FAR_SIDE, MAX_SHARE, MIN_ROWS, SEAM_MARGIN, Band,
                               band_coef, far_band, most_rows, seam_keep)
from vtrack.vision.sizes import MIN_BOXES, REFIT_EVERY
from vtrack.vision.stabilise import Following, Stabiliser, rescale

MIN_PIXELS = 150
SMALL = FAR_SIDE * np.sqrt(MIN_PIXELS)   # the band's edge: 24.5 mask px at the default


def test_band_where_the_scale_field_says_vehicles_are_small():
    # s = 4 + 60 v mask px on a 640x360 mask of a 1280x720 frame: s = SMALL at v = 0.342
    band = far_band(np.array([4.0, 0.0, 60.0]), 360, 2.0, 720, MIN_PIXELS)
    v = (SMALL - 4.0) / 60.0
    assert band.seam == int(v * 720)
    assert band.rows == int(np.ceil(band.seam + SEAM_MARGIN * SMALL * 2.0))
    # vehicles large everywhere (a view from above), growing upward, or a thin band: none
    assert far_band(np.array([40.0, 0.0, 5.0]), 360, 2.0, 720, MIN_PIXELS) is None
    assert far_band(np.array([4.0, 0.0, -60.0]), 360, 2.0, 720, MIN_PIXELS) is None
    assert far_band(np.array([SMALL - 0.05, 0.0, 60.0]), 360, 2.0, 720,
                    MIN_PIXELS) is None   # seam under MIN_ROWS
    assert MIN_ROWS > 0
    # never more than MAX_SHARE of the frame, nor more rows than are sampled for it
    band = far_band(np.array([1.0, 0.0, 10.0]), 360, 2.0, 720, MIN_PIXELS)
    assert band.seam == int(MAX_SHARE * 720) and band.rows <= 720
    assert band.rows == most_rows(360, 2.0, 720, MIN_PIXELS)
    for height in (575, 576, 1079, 1080):   # a mask of round(height / 2) rows
        band = far_band(np.array([1.0, 0.0, 10.0]), round(height / 2), height / round(
            height / 2), height, MIN_PIXELS)
        assert band.rows == most_rows(round(height / 2), height / round(height / 2),
                                      height, MIN_PIXELS) <= height


def test_band_field_gives_the_centre_columns_side_at_full_resolution():
    coef, scale, mask_h, rows = np.array([4.0, 30.0, 60.0]), 2.0, 360, 300
    full = band_coef(coef, scale, mask_h, rows)
    assert full[1] == 0   # the side on a row is the one at the centre column
    for x, y in [(100.0, 20.0), (900.0, 250.0)]:
        main = coef[0] + coef[1] * 0.5 + coef[2] * (y / scale) / mask_h
        band = full[0] + full[1] * x / 1280 + full[2] * y / rows
        assert band == pytest.approx(scale * main, rel=1e-12)


def test_seam_keeps_each_vehicle_once():
    band = Band(seam=100, rows=150)
    main = np.array([[10, 60, 20, 20], [10, 95, 20, 20], [10, 300, 40, 40]], float)
    far = np.array([[10, 60, 20, 20],      # above the seam: the band's
                    [10, 95, 20, 20],      # centred below it: the first detector's
                    [50, 130, 30, 19.5],   # cut by the band's bottom edge (149)
                    [50, 5, 8, 6]], float)
    keep, keep_far = seam_keep(main, far, band)
    assert keep.tolist() == [False, True, True]
    assert keep_far.tolist() == [True, False, False, True]


def test_following_stabiliser_takes_the_leaders_motion_rescaled():
    leader = Stabiliser(320, 180, probe_frames=10, still_px=0.5)
    leader.applied = np.array([[1.0, 0.0, 1.5], [0.0, 1.0, -2.0]])
    follow = Following(leader, 2.0, 2.0)
    image = np.random.default_rng(0).integers(0, 255, (40, 640, 3), dtype=np.uint8)
    warped, m = follow(image)
    assert np.allclose(m, rescale(leader.applied, 2.0, 2.0))
    assert np.allclose(m[:, 2], [3.0, -4.0])
    assert warped.shape == image.shape and not np.array_equal(warped, image)
    assert follow.moved == leader.moved


def _frame(rng: np.random.Generator, x: float) -> np.ndarray:
    """A 1280x720 road-grey frame with sensor noise and a dark 14x10 px car at (x, 40)."""
    image = np.clip(rng.normal(120, 2, (720, 1280, 3)), 0, 255).astype(np.uint8)
    image[40:50, int(x):int(x) + 14] = 30
    return image


def _perspective(n: int) -> np.ndarray:
    """Predicted boxes (n, 4) of a mast view, frame pixels: side 4 + 150 y / 720."""
    y = np.linspace(60, 680, n)
    s = 4 + 150 * y / 720
    return np.column_stack([np.full(n, 400.0) - s / 2, y - s / 2, s, s])


def test_far_band_finds_a_car_the_halved_frame_loses():
    """A car 14x10 px at the top of a 1280x720 frame is 7x5 px at the detection resolution,
    under min_pixels: the first detector never finds it, the band (at full resolution,
    its floor in vehicle units) does once the tracked boxes show a far end."""
    rng = np.random.default_rng(3)
    cfg = DetectorConfig(init_background_seconds=0, stabilise=False, min_motion=0)
    plain = MotionDetector(cfg, 1280, 720, fps=5)   # a sample every 2nd frame
    far = MotionDetector(cfg, 1280, 720, fps=5, far=True)
    assert far.far_wanted and not plain.far_wanted
    predicted = _perspective(10)
    seen_plain = seen_far = 0
    started = None
    for k in range(1, 140):
        x = 100 + 4 * k
        image = _frame(rng, x)
        a, b = plain.detect(image, predicted), far.detect(image, predicted)
        seen_plain += int((a.centers[:, 1] < 80).sum())
        top = b.boxes[b.centers[:, 1] < 80]
        # only the car, where it is now: the band's background, estimated from the rows
        # sampled while the car drove through them, holds no ghost of it
        assert np.all(np.abs(top[:, 0] - x) <= 3) and np.all(np.abs(top[:, 1] - 40) <= 3)
        seen_far += len(top)
        if started is None and far.band is not None:
            started = k
    assert started is not None and started % REFIT_EVERY == 0
    assert started * 10 >= MIN_BOXES
    assert far.band.seam > 50 and far._far_from == started + FAR_LAG
    assert seen_plain == 0
    # the band's background is estimated from its samples: it finds the car from its
    # first frame on, without MOG2's warm-up
    assert seen_far == 139 - (started + FAR_LAG) + 1


def test_far_band_only_where_the_detector_halves_the_frame():
    cfg = DetectorConfig(init_background_seconds=0)
    assert not MotionDetector(cfg, 640, 360, far=True).far_wanted   # not downscaled
    assert MotionDetector(cfg, 1280, 720, far=True).sizes is not None
    assert MotionDetector(cfg, 1280, 720).sizes is None
