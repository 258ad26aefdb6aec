"""Seed 001's per-vehicle measurement: position plus finite-difference velocity and
acceleration (eqs. 24-26, H = I6), formed from a track's last detections at their real times.

For detections p_k, p_{k-1}, p_{k-2} at spacings h1 = t_k - t_{k-1}, h2 = t_{k-1} - t_{k-2}:

    v = (p_k - p_{k-1}) / h1
    a = 2 [(p_k - p_{k-1}) / h1 - (p_{k-1} - p_{k-2}) / h2] / (h1 + h2)

(equal spacing gives the seed's (p_k - 2 p_{k-1} + p_{k-2}) / dt^2). Per axis (p, v, a) = D
(p_k, p_{k-1}, p_{k-2}), so white position noise sigma^2 gives R_axis = sigma^2 D D'
(SEEDS 3.1; the equal-spacing case is the matrix printed there).
"""

from __future__ import annotations

import numpy as np


def difference_operator(h1: np.ndarray, h2: np.ndarray) -> np.ndarray:
    """D (..., 3, 3) mapping (p_k, p_{k-1}, p_{k-2}) of one axis to (p, v, a)."""
    h1 = np.asarray(h1, dtype=float)
    h2 = np.asarray(h2, dtype=float)
    D = np.zeros(h1.shape + (3, 3))
    D[..., 0, 0] = 1.0
    D[..., 1, 0] = 1.0 / h1
    D[..., 1, 1] = -1.0 / h1
    D[..., 2, 0] = 2.0 / (h1 * (h1 + h2))
    D[..., 2, 1] = -2.0 / (h1 * h2)
    D[..., 2, 2] = 2.0 / (h2 * (h1 + h2))
    return D


def finite_difference_measurement(points: np.ndarray, times: np.ndarray, count: np.ndarray,
                                  sigma: float | np.ndarray, position_only: bool = False
                                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measurements of N tracks in the state layout [x, y, vx, vy, ax, ay].

    points (N, 3, 2): the last three detected centres, newest first; times (N, 3) their times;
    count (N,): how many of them exist (1, 2 or 3); sigma: the std of each detected centre, a
    number or (N, 3, 2) per detection and axis (R_axis = D diag(sigma^2) D'). Returns z (N, 6),
    R (N, 6, 6) and the mask
    (N, 6) of rows present: a track with one detection measures its position only, with two
    also its velocity (eqs. 24-25); position_only keeps only the position rows.
    """
    n = len(points)
    h1 = times[:, 0] - times[:, 1]
    h2 = times[:, 1] - times[:, 2]
    # Unused spacings get a harmless placeholder; their rows are masked out below.
    h1 = np.where(count >= 2, h1, 1.0)
    h2 = np.where(count >= 3, h2, 1.0)
    D = difference_operator(h1, h2)                          # (N, 3, 3)
    pva = np.einsum("nij,njd->nid", D, points)                # (N, 3 derivs, 2 axes)
    z = pva.reshape(n, 6)                                     # [x, y, vx, vy, ax, ay]
    var = np.broadcast_to(np.asarray(sigma, dtype=float) ** 2, (n, 3, 2))
    R = np.zeros((n, 6, 6))
    for axis in (0, 1):
        R[:, axis::2, axis::2] = (D * var[:, None, :, axis]) @ np.swapaxes(D, -1, -2)
    rows = np.repeat(np.arange(3), 2)[None, :]                # derivative order of each row
    order = np.minimum(count, 1 if position_only else 3)[:, None]
    mask = rows < order
    return z, R, mask


def nested_centre(pred: np.ndarray, size: np.ndarray, boxes: np.ndarray, sigma: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """A detected box as a measurement (z, var) of a track's centre (K, 2 each).

    A detection smaller than the vehicle (partly hidden by an occluder or the image border)
    or larger (merged with a shadow, a ghost or another vehicle) only says that the track's
    box (predicted centre `pred`, size `size`) and the detected box are nested. Per axis that
    puts the vehicle's centre in the interval between d0 + s/2 and d1 - s/2 (detection
    [d0, d1], track box size s), of length |w_det - s|; for a detection of the vehicle's size
    it is the detection's centre. z is the prediction clipped to that interval and its
    variance is the detector's sigma^2 plus that of a uniform spread over the interval,
    L^2 / 12.
    """
    half = size / 2
    a = boxes[:, :2] + half
    b = boxes[:, :2] + boxes[:, 2:] - half
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    z = np.clip(pred, lo, hi)
    return z, sigma**2 + (hi - lo) ** 2 / 12.0
