"""The sparse, per-component assignment must equal one dense Hungarian over all pairs."""

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from vtrack.tracking.association import assign, gated_pairs


@pytest.mark.parametrize("seed", range(20))
def test_assign_matches_dense_hungarian(seed):
    rng = np.random.default_rng(seed)
    n_t, n_d = rng.integers(1, 40, size=2)
    dense = np.where(rng.random((n_t, n_d)) < 0.08, rng.random((n_t, n_d)) * 10, np.inf)
    ti, di = np.nonzero(np.isfinite(dense))
    mt, md = assign(ti, di, dense[ti, di], n_t, n_d)
    assert len(set(mt)) == len(mt) and len(set(md)) == len(md)
    assert np.all(np.isfinite(dense[mt, md]))
    big = 1e9
    r, c = linear_sum_assignment(np.where(np.isfinite(dense), dense, big))
    real = dense[r, c] < big
    assert len(mt) == real.sum()  # as many pairs as the dense optimum
    assert dense[mt, md].sum() == pytest.approx(dense[r, c][real].sum(), abs=1e-9)


def test_gated_pairs_is_the_mahalanobis_gate():
    pred = np.array([[0.0, 0.0], [100.0, 0.0]])
    P = np.array([np.diag([4.0, 1.0]), np.diag([1.0, 1.0])])
    dets = np.array([[3.0, 0.0], [0.0, 3.0], [101.0, 0.0]])
    var = np.ones((1, 2))
    ti, di, cost = gated_pairs(pred, P, dets, 9.21, 50.0,
                               lambda t, d: (dets[d], np.repeat(var, len(d), axis=0)), 8)
    # (3, 0) vs S = diag(5, 2): d2 = 1.8 (in); (0, 3): d2 = 4.5 (in); (101, 0): 0.5 (in)
    got = {(int(t), int(d)): c for t, d, c in zip(ti, di, cost, strict=True)}
    assert set(got) == {(0, 0), (0, 1), (1, 2)}
    assert got[(0, 0)] == pytest.approx(9 / 5 + np.log(10.0))
    assert got[(1, 2)] == pytest.approx(1 / 2 + np.log(4.0))
