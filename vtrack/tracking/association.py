"""Gated global-nearest-neighbour assignment that scales: a k-d tree proposes candidate
pairs, Mahalanobis gating prunes them, and the optimal assignment is solved per connected
group of tracks and detections (one big dense Hungarian costs ~35 ms at 1000 x 1000)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from vtrack.boxes import centre


def nearest_pairs(queries: np.ndarray, points: np.ndarray, radius: float, k: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(query, point) index pairs: each query's k nearest points within `radius`, found with a
    k-d tree in one vectorised query (no Python loop over queries); a point beyond the k
    nearest is not paired even within the radius."""
    e = np.empty(0, dtype=int)
    if len(queries) == 0 or len(points) == 0:
        return e, e
    k = min(k, len(points))
    _, idx = cKDTree(points).query(queries, k=k, distance_upper_bound=radius)
    qi = np.repeat(np.arange(len(queries)), k)
    pi = idx.reshape(len(queries), k).ravel()
    found = pi < len(points)
    return qi[found], pi[found]


def gated_pairs(pred: np.ndarray, P: np.ndarray, dets: np.ndarray, gate: float,
                max_radius: float | np.ndarray,
                pair_measurement: Callable[[np.ndarray, np.ndarray],
                                           tuple[np.ndarray, np.ndarray]],
                candidates: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Candidate (track, detection) pairs with squared Mahalanobis distance d2 <= gate.

    pred (T, 2) predicted positions with covariances P (T, 2, 2), dets (D, 2) detection
    centres; pair_measurement(ti, di) gives each pair's measured position z (K, 2) and its
    variances var (K, 2), so nu = z - pred and S = P + diag(var). Each track's `candidates`
    nearest detections within its max_radius (T,) are the candidates (a k-d tree query).
    Returns track indices, detection indices and the cost d2 + ln det S of each pair.
    """
    if len(pred) == 0:
        e = np.empty(0, dtype=int)
        return e, e, np.empty(0)
    max_radius = np.broadcast_to(np.asarray(max_radius, dtype=float), (len(pred),))
    ti, di = nearest_pairs(pred, dets, float(np.max(max_radius)), candidates)
    near = np.hypot(*(dets[di] - pred[ti]).T) <= max_radius[ti]
    ti, di = ti[near], di[near]
    if len(ti) == 0:
        return ti, di, np.empty(0)
    z, var = pair_measurement(ti, di)
    diff = z - pred[ti]
    a, b, c = P[ti, 0, 0] + var[:, 0], P[ti, 0, 1], P[ti, 1, 1] + var[:, 1]
    det = a * c - b * b                                   # 2x2 closed forms
    d2 = (c * diff[:, 0] ** 2 - 2 * b * diff[:, 0] * diff[:, 1] + a * diff[:, 1] ** 2) / det
    ok = d2 <= gate
    return ti[ok], di[ok], d2[ok] + np.log(det[ok])


def assign(ti: np.ndarray, di: np.ndarray, cost: np.ndarray, n_tracks: int, n_dets: int
           ) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-cost one-to-one assignment over the candidate pairs, solved per connected
    component (1x1 components directly, larger ones with scipy's linear_sum_assignment)."""
    if len(ti) == 0:
        e = np.empty(0, dtype=int)
        return e, e
    # A pair whose track and detection have no other candidate is a component of its own.
    single = ((np.bincount(ti, minlength=n_tracks)[ti] == 1)
              & (np.bincount(di, minlength=n_dets)[di] == 1))
    out_t = [ti[single]]
    out_d = [di[single]]
    ti, di, cost = ti[~single], di[~single], cost[~single]
    if len(ti) == 0:
        return out_t[0], out_d[0]
    graph = coo_matrix((np.ones(len(ti)), (ti, n_tracks + di)),
                       shape=(n_tracks + n_dets,) * 2)
    _, label = connected_components(graph, directed=False)
    order = np.argsort(label[ti], kind="stable")
    starts = np.flatnonzero(np.diff(label[ti][order], prepend=-1))
    for sel in np.split(order, starts[1:]):
        rows, r_inv = np.unique(ti[sel], return_inverse=True)
        cols, c_inv = np.unique(di[sel], return_inverse=True)
        big = 1e9
        M = np.full((len(rows), len(cols)), big)
        M[r_inv, c_inv] = cost[sel]
        r, k = linear_sum_assignment(M)
        ok = M[r, k] < big
        out_t.append(rows[r[ok]])
        out_d.append(cols[k[ok]])
    return np.concatenate(out_t), np.concatenate(out_d)


def points_in_boxes(points: np.ndarray, boxes: np.ndarray, candidates: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(box, point) index pairs with the point inside the box (x, y, w, h), among each box's
    `candidates` nearest points (a box holds a few vehicle centres at most)."""
    c = centre(boxes)
    radius = float(np.hypot(boxes[:, 2], boxes[:, 3]).max()) / 2 + 1e-9 if len(boxes) else 0.0
    bi, pi = nearest_pairs(c, points, radius, candidates)
    inside = np.all(np.abs(points[pi] - c[bi]) <= boxes[bi, 2:] / 2, axis=1)
    return bi[inside], pi[inside]
