"""Seed 004's SIIM fuzzy EKF (vtrack.adaptive.siim, kind siim-ekf): the SIIM fuzzy system's
properties (SEEDS 8 item 7) and the adaptation of Q and R."""

import numpy as np
import pytest

from vtrack.adaptive.siim import siim_alpha
from vtrack.estimation.montecarlo import run_generators
from vtrack.experiments import siim as si
from vtrack.filter_kinds import make_filter


def test_siim_alpha_properties():
    """alpha(0,0)=0, alpha(1,1)=M, alpha(1,0)=M/2, alpha(0.5,0)=0.282 M; odd; monotone."""
    assert siim_alpha(0.0, 0.0) == pytest.approx(0.0, abs=1e-15)
    assert siim_alpha(1.0, 1.0) == pytest.approx(1.0)
    assert siim_alpha(1.0, 0.0) == pytest.approx(0.5)
    assert siim_alpha(0.5, 0.0) == pytest.approx(0.28219, abs=1e-5)
    assert siim_alpha(1.0, 1.0, M=2e-4) == pytest.approx(2e-4)
    x = np.linspace(-1, 1, 101)
    for other in (-0.7, 0.0, 0.4):
        a1 = siim_alpha(x, other)
        a2 = siim_alpha(other, x)
        assert np.all(np.diff(a1) > 0) and np.all(np.diff(a2) > 0)
    np.testing.assert_allclose(siim_alpha(x, -x), 0.0, atol=1e-12)
    np.testing.assert_allclose(siim_alpha(-x, 0.3), -siim_alpha(x, -0.3), atol=1e-12)


def test_siim_adaptation_direction_and_clamps():
    sc = si.Scenario2(samples=201)
    motion, meas = sc.models()
    f = make_filter("siim-ekf", motion, meas, np.array(sc.xhat0), 10 * np.eye(3), gamma=0.5)
    (rng, _), = run_generators(0, 1)
    _, z = si.simulate2(sc, rng)
    alphas = []
    for zk in z:
        f.step(sc.dt, np.array([zk]))
        alphas.append(f.alpha)
        assert 1e-3 <= f.q_scale <= 1e3 and 1e-3 <= f.r_scale <= 1e3
    assert np.mean(alphas) > 0            # x1 >= 0 makes alpha positive on average
    assert f.r_scale > 1.0 > f.q_scale    # so R grows and Q shrinks
    f.step(sc.dt, np.array([np.nan]))     # a missing measurement only predicts
    assert np.all(np.isfinite(f.x))
