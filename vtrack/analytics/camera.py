"""The camera above the road, recovered from the ground homography.

A pinhole camera with square pixels, no skew and its principal point at the image centre
(c_u, c_v) sees the road plane Z = 0 through G = H^-1 ~ K [r1 r2 t] with K = [[f, 0, c_u],
[0, f, c_v], [0, 0, 1]] (H&Z sec. 8.8, Zhang's plane-based calibration with one unknown).
With g1, g2 the first two columns of G after moving the principal point to the origin, r1 and
r2 are orthonormal:

    s (g1u g2u + g1v g2v) + g1w g2w = 0
    s (g1u^2 + g1v^2 - g2u^2 - g2v^2) + g1w^2 - g2w^2 = 0,    s = 1 / f^2

solved for s in the least-squares sense. Then [r1 r2 t] = K^-1 G / lambda (lambda the mean norm
of the first two columns, sign such that the road is in front of the camera) and the camera
centre is C = -R^T t, at height |C_Z| above the road. A camera looking straight down (no
perspective) or a homography that is not a pinhole view of a plane gives None.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GroundCamera:
    """Where the camera is over the road plane (metres) and its focal length (pixels)."""

    position: np.ndarray   # (2,) X, Y of the point of the road below the camera
    height: float          # camera height above the road, m
    focal: float           # f, px


def camera_from_homography(H: np.ndarray, width: int, height: int) -> GroundCamera | None:
    """Recover the camera of an image -> road homography `H` (see the module docstring)."""
    cu, cv = (width - 1) / 2.0, (height - 1) / 2.0
    G = np.array([[1, 0, -cu], [0, 1, -cv], [0, 0, 1]]) @ np.linalg.inv(H)
    g1, g2, g3 = G[:, 0], G[:, 1], G[:, 2]
    a = np.array([g1[0] * g2[0] + g1[1] * g2[1],
                  g1[0] ** 2 + g1[1] ** 2 - g2[0] ** 2 - g2[1] ** 2])
    b = np.array([g1[2] * g2[2], g1[2] ** 2 - g2[2] ** 2])
    if not np.dot(a, a) > 0:
        return None
    s = -np.dot(a, b) / np.dot(a, a)
    if not s > 0:
        return None
    f = 1.0 / np.sqrt(s)
    if not (0.05 * width < f < 50.0 * width):
        return None                     # no usable perspective (near-orthographic view)
    Kinv = np.diag([1.0 / f, 1.0 / f, 1.0])
    r1, r2, t = Kinv @ g1, Kinv @ g2, Kinv @ g3
    lam = 0.5 * (np.linalg.norm(r1) + np.linalg.norm(r2))
    r1, r2, t = r1 / lam, r2 / lam, t / lam
    if t[2] < 0:                        # the world origin must be in front of the camera
        r1, r2, t = -r1, -r2, -t
    u, _, vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    R = u @ vt                          # nearest rotation
    C = -R.T @ t
    if not np.all(np.isfinite(C)) or abs(C[2]) < 1e-6:
        return None
    return GroundCamera(position=C[:2].copy(), height=float(abs(C[2])), focal=float(f))
