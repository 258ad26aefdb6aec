"""Colour signatures (vision/colour.py) and their comparison (reidentifier.colour_similarity):
a vehicle matches itself across frames and not a vehicle of another colour."""

import numpy as np

from vtrack.tracking.reidentifier import SIGNATURE_SIZE, colour_similarity
from vtrack.vision.colour import BINS, signatures


def _scene(rng: np.random.Generator) -> np.ndarray:
    """Grey road with noise, a red car at (100, 100) and a blue one at (300, 120), 60 x 30."""
    img = np.clip(rng.normal(110, 12, (240, 480, 3)), 0, 255).astype(np.uint8)
    img[100:130, 100:160] = (30, 30, 200)      # BGR red
    img[120:150, 300:360] = (200, 60, 30)      # BGR blue
    return img


def test_a_car_matches_itself_not_another_colour():
    rng = np.random.default_rng(0)
    img = _scene(rng)
    boxes = np.array([[98, 98, 64, 34], [298, 118, 64, 34], [20, 20, 60, 30],
                      [103, 101, 58, 28]], dtype=float)   # red, blue, road, red again
    sig = signatures(img, boxes)
    assert sig.shape == (4, SIGNATURE_SIZE) == (4, int(np.prod(BINS)))
    assert np.allclose(sig.sum(axis=1), 1.0)
    sim = colour_similarity(sig, sig)
    assert np.allclose(np.diag(sim), 1.0)
    assert sim[0, 3] > 0.9                      # the red car, boxed a little differently
    assert sim[0, 1] < 0.1 and sim[0, 2] < 0.1  # not the blue car, not the road


def test_a_box_outside_the_image_has_no_signature():
    img = _scene(np.random.default_rng(1))
    sig = signatures(img, np.array([[500.0, 10.0, 20.0, 20.0], [-40.0, 10.0, 20.0, 20.0]]))
    assert not sig.any()
    assert signatures(img, np.zeros((0, 4))).shape == (0, SIGNATURE_SIZE)
