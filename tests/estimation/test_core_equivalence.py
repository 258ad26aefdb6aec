"""Linear-Gaussian case: every filter kind must give the KF's mean and covariance."""

import numpy as np
import pytest

from vtrack.filter_kinds import make_filter
from vtrack.estimation.models import WienerVelocity, position_measurement


def _run(kind, steps=60, seed=3, **opts):
    rng = np.random.default_rng(seed)
    motion = WienerVelocity(q=0.5)
    meas = position_measurement(4, sigma=[0.3, 0.4])
    f = make_filter(kind, motion, meas, np.array([0.0, 0.0, 1.0, 0.5]),
                    np.diag([1.0, 2.0, 3.0, 4.0]), **opts)
    xs, Ps = [], []
    for k in range(steps):
        z = np.array([k * 0.1, 0.05 * k]) + rng.normal(0, 0.3, 2)
        if k % 7 == 3:
            z[1] = np.nan  # a missing cell
        if k % 11 == 5:
            z[:] = np.nan  # a predict-only step
        f.step(0.1, z)
        xs.append(f.x.copy())
        Ps.append(f.P.copy())
    return np.array(xs), np.array(Ps)


@pytest.mark.parametrize("kind,opts", [
    ("ekf", {}), ("ukf", {}), ("ukf", {"alpha": 0.5, "beta": 2.0, "kappa": 0.0}),
    ("ckf", {}), ("srukf", {}), ("srukf", {"alpha": 1.0, "beta": 2.0, "kappa": 1.0}),
])
def test_all_filters_equal_kf_on_linear_gaussian(kind, opts):
    x_kf, P_kf = _run("kf")
    x, P = _run(kind, **opts)
    np.testing.assert_allclose(x, x_kf, rtol=0, atol=1e-9)
    np.testing.assert_allclose(P, P_kf, rtol=0, atol=1e-9)


def test_covariances_stay_symmetric_pd():
    _, Ps = _run("ukf")
    for P in Ps:
        np.testing.assert_array_equal(P, P.T)
        assert np.linalg.eigvalsh(P).min() > 0
