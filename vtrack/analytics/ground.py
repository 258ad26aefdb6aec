"""What a box and its filtered state say about the vehicle on the road (calibrated runs).

Ground contact point: the bottom centre of the box, g = (x, y + h/2), with (x, y) the filtered
centre; its image velocity is g' = (vx, vy + h'/2) with h' the box height's rate (the tracker's
size_rates). Road velocity: v = J_H(g) g' (calibration.Calibration.jacobian), so the speed
comes from the filtered state, not from differences of noisy boxes.

Length along the direction of travel u (the road velocity's direction): the box's four
corners are mapped to the road as if they lay on it (P_i), and the footprint is the spread of
their positions along u, L_flat = max_i P_i.u - min_j P_j.u. A corner on the bottom edge is
where the vehicle meets the road; a corner on the top edge is the top of the vehicle's far
end, so its flat image lands beyond the vehicle by (H / h_c) |P - C| (similar triangles: a
point at height H seen from a camera at height h_c above the road point C). That is the bias
of the flat footprint: for a vehicle seen along the road at distance d it over-estimates the
length by about H d / h_c (a 1.5 m high car 30 m from a 9 m mast: +5 m). With the camera
recovered from the homography (camera.py), and rho_i = 1 for a top corner, 0 for a bottom one,
the true length is linear in the vehicle's height:

    L_flat = L + H k,   k = [rho_hi (P_hi - C).u - rho_lo (P_lo - C).u] / h_c     (per frame)

(hi, lo: the corners giving the max and the min). vehicles.LengthFit turns the frames'
(L_flat, k) into a length and a class. Without a camera k = 0: the flat footprint (exact for a
view straight down, where boxes are footprints).
"""

from __future__ import annotations

import numpy as np

from vtrack.analytics.calibration import Calibration
from vtrack.analytics.camera import GroundCamera


def contact_points(states: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(K, 2) bottom centres g = (x, y + h/2) of the boxes around the filtered centres."""
    return np.column_stack([states[:, 0], states[:, 1] + boxes[:, 3] / 2.0])


def contact_velocities(states: np.ndarray, size_rates: np.ndarray) -> np.ndarray:
    """(K, 2) image velocities g' = (vx, vy + h'/2) of the contact points, px/s."""
    return np.column_stack([states[:, 2], states[:, 3] + size_rates[:, 1] / 2.0])


def speed_sigmas(calib: Calibration, g: np.ndarray, v_road: np.ndarray,
                 covariances: np.ndarray) -> np.ndarray:
    """(K,) std of the road speed, m/s: the filter's velocity covariance P_v (px^2/s^2)
    through the Jacobian, along the travel direction u: sigma^2 = u' J P_v J' u."""
    J = calib.jacobian(g)
    speed = np.hypot(v_road[:, 0], v_road[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        u = v_road / speed[:, None]
    Ju = np.einsum("kij,ki->kj", J, u)                    # J' u
    var = np.einsum("ki,kij,kj->k", Ju, covariances[:, 2:4, 2:4], Ju)
    return np.sqrt(np.maximum(var, 0.0))


def footprint_samples(calib: Calibration, camera: GroundCamera | None, boxes: np.ndarray,
                      v_road: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per track (L_flat, k) of the module docstring: the flat footprint along the travel
    direction, m, and the height coefficient (0 without a camera)."""
    n = len(boxes)
    x0, y0 = boxes[:, 0], boxes[:, 1]
    x1, y1 = x0 + boxes[:, 2], y0 + boxes[:, 3]
    corners = np.stack([np.column_stack(c) for c in ((x0, y1), (x1, y1), (x0, y0), (x1, y0))],
                       axis=1)                                     # (n, 4, 2)
    rho = np.array([0.0, 0.0, 1.0, 1.0])                          # fraction up the box
    P = calib.to_world(corners)                                    # (n, 4, 2)
    speed = np.hypot(v_road[:, 0], v_road[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        u = v_road / speed[:, None]
    s = np.einsum("nkj,nj->nk", P, u)                              # along travel, m
    ok = np.all(np.isfinite(s), axis=1) & (speed > 0)
    L = np.full(n, np.nan)
    k = np.zeros(n)
    if not ok.any():
        return L, k
    s_ok = s[ok]
    hi, lo = np.argmax(s_ok, axis=1), np.argmin(s_ok, axis=1)
    rows = np.arange(len(s_ok))
    L[ok] = s_ok[rows, hi] - s_ok[rows, lo]
    if camera is not None:
        c = np.einsum("j,nj->n", camera.position, u[ok])
        k[ok] = (rho[hi] * (s_ok[rows, hi] - c) - rho[lo] * (s_ok[rows, lo] - c)) / camera.height
    return L, k
