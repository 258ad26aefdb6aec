"""Missing measurement cells (NaN): a partial row updates with the present cells only, an
all-NaN row only predicts, inf is an error. Checked for every kind on a nonlinear model."""

import numpy as np
import pytest
import seed000 as S

from vtrack.filter_kinds import make_filter
from vtrack.estimation.linalg import EstimationError
from vtrack.estimation.models import Bearings, WienerVelocity

SENSORS3 = np.array([[1.0, -2.0], [1.0, 2.0], [1.0 - 2.0 * np.sqrt(3.0), 0.0]])
SIGMAS3 = np.array([0.05, 0.07, 0.03])
KINDS = ["ekf", "ukf", "ckf", "srukf"]


def _filter(kind, sensors=SENSORS3, sigma=SIGMAS3):
    return make_filter(kind, WienerVelocity(0.1), Bearings(sensors, sigma), S.M0_TRUE,
                       S.P0)


def _warm(f, zs):
    for z in zs:
        f.step(S.DT, z)


@pytest.mark.parametrize("kind", KINDS)
def test_partial_row_equals_model_of_present_sensors(kind):
    rng = np.random.default_rng(0)
    truth = S.model_matched_truth(rng, 1, 40)[0]
    zs = S.bearings(truth, rng, SENSORS3, SIGMAS3)
    for keep in ([0, 2], [1], [2]):
        full = _filter(kind)
        _warm(full, zs[:30])
        # the reference: a filter whose measurement model has only the present sensors,
        # carrying the same prior
        sub = make_filter(kind, WienerVelocity(0.1),
                          Bearings(SENSORS3[keep], SIGMAS3[keep]), full.x, full.P)
        for z in zs[30:]:
            z_nan = np.full(3, np.nan)
            z_nan[keep] = z[keep]
            info = full.step(S.DT, z_nan)
            sub.step(S.DT, z[keep])
            np.testing.assert_allclose(full.x, sub.x, rtol=0, atol=1e-12)
            np.testing.assert_allclose(full.P, sub.P, rtol=0, atol=1e-12)
            assert info.nu.shape == (len(keep),)
        # and it is not a no-op: the full-row filter differs from the partial-row one
        full2 = _filter(kind)
        _warm(full2, zs)
        assert np.abs(full2.x - full.x).max() > 1e-6


@pytest.mark.parametrize("kind", KINDS)
def test_all_nan_row_only_predicts(kind):
    rng = np.random.default_rng(1)
    zs = S.bearings(S.model_matched_truth(rng, 1, 20)[0], rng, SENSORS3, SIGMAS3)
    a, b = _filter(kind), _filter(kind)
    _warm(a, zs)
    _warm(b, zs)
    info = a.step(0.05, np.full(3, np.nan))
    b.predict(0.05)
    assert info is None and a.last is None
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.P, b.P)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("bad", [np.inf, -np.inf])
def test_inf_cell_raises(kind, bad):
    f = _filter(kind)
    f.predict(S.DT)
    x, P = f.x.copy(), f.P.copy()
    with pytest.raises(EstimationError):
        f.update(np.array([0.1, bad, np.nan]))
    np.testing.assert_array_equal(f.x, x)  # nothing was half-applied
    np.testing.assert_array_equal(f.P, P)
