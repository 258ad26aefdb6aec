"""Seed 003's fuzzy-aided KFs (vtrack.adaptive.fuzzy: fuzzy-r, fuzzy-q): the Mamdani FIS of
the paper's Table 1 and the filter kinds."""

import itertools

import numpy as np
import pytest

from vtrack.adaptive.fuzzy import (
    EM_FIS,
    HAMID_FIS,
    HAMID_INPUT_TERMS,
    HAMID_RULES,
    LEVELS,
    fuzzy_adjustment,
)
from vtrack.estimation.models import WienerVelocity, position_measurement
from vtrack.filter_kinds import make_filter


# ----------------------------------------------------------------------- FIS properties


def test_rule_table_is_the_degree_of_matching_principle():
    """Table 1 read with NS < ZE < L: S above Sr -> decrease R, below -> increase, same ->
    maintain (SEEDS 5.3), for all nine rules."""
    assert len(HAMID_RULES) == 9
    level = {t: i for i, t in enumerate(LEVELS)}
    for (sr, s), action in HAMID_RULES.items():
        expected = "D" if level[s] > level[sr] else "I" if level[s] < level[sr] else "M"
        assert action == expected, (sr, s, action)
    assert HAMID_RULES[("NS", "L")] == "D"  # the paper's worded example


def test_fis_output_sign_follows_the_levels():
    centres = {t: c for t, (c, _) in HAMID_INPUT_TERMS.items()}
    for sr, s in itertools.product(LEVELS, LEVELS):
        out = float(HAMID_FIS(centres[sr], centres[s]))
        if centres[s] > centres[sr]:
            assert out < -0.3
        elif centres[s] < centres[sr]:
            assert out > 0.3
        else:
            assert abs(out) < 1e-12


def test_fis_is_antisymmetric_and_zero_on_the_diagonal():
    rng = np.random.default_rng(0)
    a, b = rng.uniform(-1, 1, (2, 200))
    np.testing.assert_allclose(HAMID_FIS(a, b), -HAMID_FIS(b, a), atol=1e-12)
    np.testing.assert_allclose(HAMID_FIS(a, a), 0.0, atol=1e-12)
    assert np.all(np.abs(HAMID_FIS(a, b)) <= 1.0)


def test_adjustment_direction_from_the_statistics():
    ref = np.array([25.0, 25.0, 25.0])
    S = np.array([25.0, 25.0, 25.0])
    Sr = np.array([100.0, 25.0, 5.0])   # sees more / equal / less innovation than predicted
    for rules in (9, 3):
        act = fuzzy_adjustment(S, Sr, ref, rules)
        assert act[0] > 0.1 and abs(act[1]) < 1e-9 and act[2] < -0.1, (rules, act)
    np.testing.assert_allclose(EM_FIS(np.array([-1.0, 0.0, 1.0]))[1], 0.0, atol=1e-12)
    with pytest.raises(ValueError):
        fuzzy_adjustment(S, Sr, ref, 5)


# ------------------------------------------------------------------------- filter kinds


def _linear_run(kind, z_seq, **opts):
    f = make_filter(kind, WienerVelocity(0.5), position_measurement(4, [0.3, 0.4]),
                    np.zeros(4), np.eye(4), **opts)
    xs = []
    for z in z_seq:
        f.step(0.1, z)
        xs.append(f.x.copy())
        P = f.P
        np.testing.assert_array_equal(P, P.T)
        assert np.linalg.eigvalsh(P).min() > 0
    return f, np.array(xs)


def _zs(n=120, seed=0, scale=1.0):
    rng = np.random.default_rng(seed)
    return [np.array([0.1 * k, 0.05 * k]) + scale * rng.normal(0, [0.3, 0.4]) for k in range(n)]


@pytest.mark.parametrize("kind", ["fuzzy-r", "fuzzy-q"])
def test_equals_kf_until_the_window_is_full(kind):
    zs = _zs(40)
    _, x_kf = _linear_run("kf", zs)
    _, x = _linear_run(kind, zs, window=1000)
    np.testing.assert_allclose(x, x_kf, rtol=0, atol=1e-12)
    _, x15 = _linear_run(kind, zs)               # default window 15: first 15 updates exact
    np.testing.assert_allclose(x15[:15], x_kf[:15], rtol=0, atol=1e-12)


def test_fuzzy_r_tracks_a_wrong_r_and_respects_its_bounds():
    # measurement noise 3x the assumed std: R must grow; 1/10: R must shrink
    f, _ = _linear_run("fuzzy-r", _zs(400, scale=3.0))
    assert np.all(np.diag(f.R) > 2.0 * np.diag(f.R_nom))
    f, _ = _linear_run("fuzzy-r", _zs(400, scale=0.1))
    assert np.all(np.diag(f.R) < 0.5 * np.diag(f.R_nom))
    # absurd innovations: R is held at its ceiling, never beyond
    f, _ = _linear_run("fuzzy-r", _zs(600, scale=300.0))
    assert np.all(np.diag(f.R) <= 100.0 * np.diag(f.R_nom) + 1e-12)
    f, _ = _linear_run("fuzzy-q", _zs(600, scale=300.0))
    assert np.all(f.q_scale <= 100.0 + 1e-12) and np.all(f.q_scale > 1.0)


def test_missing_cells_are_handled():
    zs = _zs(80)
    for k in range(0, 80, 3):
        zs[k] = zs[k].copy()
        zs[k][1] = np.nan          # axis 1 missing every third step
    zs[10] = np.array([np.nan, np.nan])
    for kind, opts in (("fuzzy-r", {}), ("fuzzy-q", {}), ("siim-ekf", {"gamma": 0.05})):
        f, x = _linear_run(kind, zs, **opts)
        assert np.all(np.isfinite(x))
    f, _ = _linear_run("fuzzy-r", zs)
    assert f.window.count[0] == 79 and f.window.count[1] == 79 - 27


def test_options_and_errors():
    f = make_filter("fuzzy-r", WienerVelocity(0.5), position_measurement(4, 0.3), np.zeros(4),
                    np.eye(4), window=10.0, rules=3.0, step=0.1)
    assert f.window.size == 10 and f.rules == 3 and f.kind == "fuzzy-r"
    with pytest.raises(ValueError):
        make_filter("fuzzy-q", WienerVelocity(0.5), position_measurement(4, 0.3), np.zeros(4),
                    np.eye(4), gamma=1.0)
    with pytest.raises(ValueError):
        make_filter("fuzzy-r", WienerVelocity(0.5), position_measurement(4, 0.3), np.zeros(4),
                    np.eye(4), window=2.5)
    with pytest.raises(ValueError):
        make_filter("siim-ekf", WienerVelocity(0.5), position_measurement(4, 0.3), np.zeros(4),
                    np.eye(4), gamma=2.0)
