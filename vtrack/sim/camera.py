"""A pinhole camera over the road plane.

World frame: X, Y in metres on the road plane (Z = 0), Z up. Camera frame (OpenCV): x right,
y down, z along the optical axis. A world point P maps to

    p_c = R (P - C),   u = f x_c / z_c + c_x,   v = f y_c / z_c + c_y

and a road-plane point (X, Y, 0) to the pixel H [X, Y, 1]^T with the homography
H = K [r_1  r_2  -R C] (r_i the columns of R).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

NEAR_M = 0.3               # points closer than this to the image plane are clipped


@dataclass(frozen=True)
class Camera:
    """Intrinsics (focal length and principal point in pixels), pose and image size."""

    focal: float
    cx: float
    cy: float
    R: np.ndarray          # (3, 3) world -> camera rotation
    centre: np.ndarray     # (3,) camera centre in the world
    width: int
    height: int

    @classmethod
    def looking(cls, centre: tuple[float, float, float], yaw: float, pitch: float, roll: float,
                focal: float, width: int, height: int) -> Camera:
        """A camera at `centre` whose optical axis has azimuth `yaw` (from +X towards +Y) and
        points `pitch` below the horizon, rolled by `roll` about the axis (radians)."""
        cp, sp, cy_, sy = math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
        fwd = np.array([cp * cy_, cp * sy, -sp])
        right = np.array([sy, -cy_, 0.0])
        down = np.cross(fwd, right)
        cr, sr = math.cos(roll), math.sin(roll)
        rot = np.stack([cr * right + sr * down, -sr * right + cr * down, fwd])
        return cls(focal, (width - 1) / 2, (height - 1) / 2, rot, np.asarray(centre, float),
                   width, height)

    def padded(self, margin: int) -> Camera:
        """The same camera seeing `margin` more pixels on every side."""
        return replace(self, cx=self.cx + margin, cy=self.cy + margin,
                       width=self.width + 2 * margin, height=self.height + 2 * margin)

    @property
    def K(self) -> np.ndarray:
        """Intrinsic matrix."""
        return np.array([[self.focal, 0, self.cx], [0, self.focal, self.cy], [0, 0, 1.0]])

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) in the camera frame (..., 3)."""
        return (np.asarray(points, float) - self.centre) @ self.R.T

    def pixels(self, cam_points: np.ndarray) -> np.ndarray:
        """Camera-frame points (..., 3), z > 0, to pixels (..., 2)."""
        z = cam_points[..., 2:3]
        return self.focal * cam_points[..., :2] / z + np.array([self.cx, self.cy])

    def project(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) in front of the camera to pixels (..., 2)."""
        return self.pixels(self.to_camera(points))

    def homography(self) -> np.ndarray:
        """H with pixel ~ H [X, Y, 1] for road-plane points (module docstring)."""
        t = -self.R @ self.centre
        return self.K @ np.column_stack([self.R[:, 0], self.R[:, 1], t])

    def rays(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """World directions (..., 3) of the rays through pixels (u, v) (not normalised)."""
        d = np.stack([(u - self.cx) / self.focal, (v - self.cy) / self.focal,
                      np.ones_like(u, dtype=float)], axis=-1)
        return d @ self.R

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Euclidean distance (...,) from the camera centre to world points (..., 3)."""
        return np.linalg.norm(np.asarray(points, float) - self.centre, axis=-1)


def clip_near(cam_polygon: np.ndarray, near: float = NEAR_M) -> np.ndarray:
    """The part of a convex camera-frame polygon (N, 3) with z >= near (Sutherland-Hodgman
    against one plane); (0, 3) when nothing is left."""
    out = []
    n = len(cam_polygon)
    for i in range(n):
        a, b = cam_polygon[i], cam_polygon[(i + 1) % n]
        ina, inb = a[2] >= near, b[2] >= near
        if ina:
            out.append(a)
        if ina != inb:
            t = (near - a[2]) / (b[2] - a[2])
            out.append(a + t * (b - a))
    return np.array(out).reshape(-1, 3)
