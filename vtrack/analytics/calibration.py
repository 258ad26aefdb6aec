"""Ground-plane calibration: image pixels <-> road-plane metres through a homography.

CALIB.toml (INTERFACE.md):

    frame_size = [1280, 720]          # optional: the video's size the points were picked on
    [[points]]
    image = [412.0, 633.5]            # pixel (u, v), OpenCV's 0-based origin
    world = [0.0, 0.0]                # road-plane metres (X, Y)
    ... at least 4 points, of which some 4 are in general position

Points may lie along lane lines (collinear triples are what a user measures): a homography is
fixed by any 4 correspondences no 3 of which are collinear, in the image and on the road. Such
a quadruple exists unless all the distinct points but at most one lie on one line (a set with
two points off a line L and two on it away from the off-line pair's own line always holds
one), so a set is refused only then, or when fewer than 4 points are distinct, or when the fit
is degenerate (rank < 8 or a singular H).

The homography H maps an image point to the road plane, (X, Y, 1)^T ~ H (u, v, 1)^T. It is
fitted to all the points by the normalised direct linear transform (Hartley & Zisserman,
Multiple View Geometry, alg. 4.2), not by cv2.findHomography: both point sets are moved to
their centroid and scaled to a mean distance of sqrt(2), the 2n x 9 system A h = 0 is solved
in the algebraic least-squares sense (the right singular vector of the smallest singular
value; exact for 4 points), and H is denormalised. The fit is reported by its reprojection
error per point in pixels (world points mapped into the image, |H^-1 X_i - u_i|) and in metres
(image points mapped onto the road, |H u_i - X_i|), mean and max; `warning()` says when the
largest error on the road exceeds WARN_SHARE of the points' extent (the largest distance
between two of them): a point picked or measured wrongly, which a least-squares fit spreads
over the others.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from vtrack.errors import InputError
from vtrack.fileio import read_toml

COLLINEAR_TOLERANCE = 0.01  # a triple whose height is < 1 % of its longest side is collinear
WARN_SHARE = 0.02           # warn when a point's road error exceeds 2 % of the points' extent


@dataclass(frozen=True)
class Calibration:
    """A fitted image -> road-plane homography and how well it fits its points."""

    H: np.ndarray                              # (3, 3) image -> world, H[2, 2] = 1
    image_points: np.ndarray                   # (n, 2) pixels
    world_points: np.ndarray                   # (n, 2) metres
    frame_size: tuple[int, int] | None = None  # (W, H) the points were picked on
    source: str = "calibration"

    @cached_property
    def H_inv(self) -> np.ndarray:
        """World -> image homography."""
        return np.linalg.inv(self.H)

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Image points (..., 2) -> road-plane metres (..., 2); NaN beyond the horizon."""
        return apply_homography(self.H, points, self._side)

    def to_image(self, points: np.ndarray) -> np.ndarray:
        """Road-plane points (..., 2) in metres -> pixels (..., 2)."""
        return apply_homography(self.H_inv, points)

    @cached_property
    def _side(self) -> float:
        """Sign of the homogeneous scale (H p)_3 on the road side of the horizon."""
        p = np.column_stack([self.image_points, np.ones(len(self.image_points))])
        return float(np.sign(np.median(p @ self.H[2])))

    def jacobian(self, point: np.ndarray) -> np.ndarray:
        """d(X, Y)/d(u, v) at image points (..., 2) -> (..., 2, 2); NaN beyond the horizon.

        With w = h3 . p: dX/du = (h11 - X h31)/w, dX/dv = (h12 - X h32)/w, and the same for Y
        with h2 (the derivative of the projective map X = h1 . p / h3 . p)."""
        p = np.asarray(point, dtype=float)
        w = p[..., 0] * self.H[2, 0] + p[..., 1] * self.H[2, 1] + self.H[2, 2]
        xy = self.to_world(p)
        J = np.empty(p.shape[:-1] + (2, 2))
        for r in range(2):
            for c in range(2):
                J[..., r, c] = (self.H[r, c] - xy[..., r] * self.H[2, c]) / w
        return J

    def ground_velocity(self, point: np.ndarray, image_velocity: np.ndarray) -> np.ndarray:
        """Road-plane velocity (m/s) of an image point moving at `image_velocity` (px/s):
        v_world = J(p) v_image (first order in the motion, exact for the instantaneous rate)."""
        J = self.jacobian(point)
        return np.einsum("...ij,...j->...i", J, np.asarray(image_velocity, dtype=float))

    @cached_property
    def residuals(self) -> tuple[np.ndarray, np.ndarray]:
        """Per point: the reprojection error in pixels |H^-1 X_i - u_i| and on the road in
        metres |H u_i - X_i|."""
        px = np.hypot(*(self.to_image(self.world_points) - self.image_points).T)
        m = np.hypot(*(self.to_world(self.image_points) - self.world_points).T)
        return px, m

    def errors(self) -> dict[str, Any]:
        """summary.json's figures of the fit: the number of points, the reprojection error in
        pixels and metres (mean and max over the points) and their RMS values."""
        px, m = self.residuals
        return {"points": int(len(self.image_points)),
                "reprojection_px": {"mean": float(px.mean()), "max": float(px.max())},
                "reprojection_m": {"mean": float(m.mean()), "max": float(m.max())},
                "reprojection_rms_px": float(np.sqrt(np.mean(px ** 2))),
                "world_rms_m": float(np.sqrt(np.mean(m ** 2)))}

    def warning(self) -> str | None:
        """The `warning:` text when the largest road error exceeds WARN_SHARE of the points'
        extent, else None."""
        px, m = self.residuals
        d = self.world_points[:, None, :] - self.world_points[None, :, :]
        extent = float(np.sqrt((d ** 2).sum(-1)).max())
        worst = int(np.argmax(m))
        if not m[worst] > WARN_SHARE * extent:
            return None
        return (f"{self.source}: the points fit no homography well: reprojection error up "
                f"to {m[worst]:.2f} m ({px[worst]:.1f} px, at point {worst + 1}), more than "
                f"{100 * WARN_SHARE:g} % of the points' {extent:.1f} m extent (mean "
                f"{m.mean():.2f} m, {px.mean():.1f} px); check their pixels and metres")

    def check_frame_size(self, width: int, height: int) -> None:
        """InputError when the calibration was made on a frame of another size."""
        if self.frame_size is not None and tuple(self.frame_size) != (width, height):
            raise InputError(f"{self.source}: frame_size {list(self.frame_size)} differs from "
                             f"the video's {width}x{height}")


def apply_homography(H: np.ndarray, points: np.ndarray, side: float = 0.0) -> np.ndarray:
    """p' = (H p~)_{1,2} / (H p~)_3 for points (..., 2). With `side` != 0, points whose scale
    has the other sign (beyond the plane's horizon) map to NaN."""
    p = np.asarray(points, dtype=float)
    q = p @ H[:, :2].T + H[:, 2]
    w = q[..., 2:3]
    bad = (w == 0) if side == 0 else (w * side <= 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = q[..., :2] / w
    return np.where(bad, np.nan, out)


def _normaliser(points: np.ndarray) -> np.ndarray:
    """Similarity T moving the points' centroid to 0 and their mean distance to sqrt(2)."""
    c = points.mean(axis=0)
    d = np.mean(np.hypot(*(points - c).T))
    s = math.sqrt(2) / d
    return np.array([[s, 0, -s * c[0]], [0, s, -s * c[1]], [0, 0, 1]])


def fit_homography(image: np.ndarray, world: np.ndarray) -> np.ndarray:
    """Normalised DLT (H&Z alg. 4.2): H with world ~ H image, least squares for n > 4.

    Raises ValueError when the points do not determine a homography."""
    image = np.asarray(image, dtype=float)
    world = np.asarray(world, dtype=float)
    Ti, Tw = _normaliser(image), _normaliser(world)
    a = apply_homography(Ti, image)
    b = apply_homography(Tw, world)
    n = len(a)
    A = np.zeros((2 * n, 9))
    for k, ((x, y), (X, Y)) in enumerate(zip(a, b)):
        A[2 * k] = [-x, -y, -1, 0, 0, 0, X * x, X * y, X]
        A[2 * k + 1] = [0, 0, 0, -x, -y, -1, Y * x, Y * y, Y]
    _, s, vt = np.linalg.svd(A)
    if s[7] < 1e-8 * s[0]:
        raise ValueError("the linear system is rank-deficient")
    Hn = vt[-1].reshape(3, 3)
    H = np.linalg.inv(Tw) @ Hn @ Ti
    if abs(H[2, 2]) < 1e-12 or not np.all(np.isfinite(H)):
        raise ValueError("the fitted homography is degenerate")
    H = H / H[2, 2]
    if abs(np.linalg.det(H)) < 1e-12 * np.abs(H).max() ** 3:
        raise ValueError("the fitted homography is singular")
    return H


def _degenerate(a: np.ndarray, b: np.ndarray, c: np.ndarray, tol: float) -> bool:
    """Whether the triangle a, b, c is flat: its height is below `tol` times its longest
    side (collinear points), or two of its corners coincide."""
    cross = abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    longest = max(np.hypot(*(b - a)), np.hypot(*(c - a)), np.hypot(*(c - b)))
    return bool(longest == 0 or cross / longest < tol * longest)   # height = cross / base


def general_quadruple(points: Sequence[np.ndarray], tol: float = COLLINEAR_TOLERANCE
                      ) -> tuple[int, int, int, int] | None:
    """The first 4 indices (i, j, k, l) no 3 of which are collinear or coincide in every
    point set given (image, world: the same indices), else None."""
    sets = [np.asarray(p, dtype=float) for p in points]
    n = len(sets[0])
    flat: dict[tuple[int, int, int], bool] = {}

    def bad(t: tuple[int, int, int]) -> bool:
        if t not in flat:
            flat[t] = any(_degenerate(p[t[0]], p[t[1]], p[t[2]], tol) for p in sets)
        return flat[t]

    for quad in itertools.combinations(range(n), 4):
        if not any(bad(t) for t in itertools.combinations(quad, 3)):
            return quad
    return None


def why_degenerate(points: np.ndarray, tol: float = COLLINEAR_TOLERANCE) -> str:
    """Why no 4 of `points` are in general position: fewer than 4 distinct points, or all
    but at most one of the distinct ones on one line (the only other case)."""
    pts = np.asarray(points, dtype=float)
    extent = max(float(np.hypot(*(pts - pts[0]).T).max()), 1e-300)
    distinct: list[int] = []
    for i, p in enumerate(pts):
        if all(np.hypot(*(p - pts[j])) > tol * extent for j in distinct):
            distinct.append(i)
    if len(distinct) < 4:
        return f"only {len(distinct)} distinct points (the others coincide with them)"
    best: list[int] = []
    for i, j in itertools.combinations(distinct[:3], 2):   # two of any 3 are on the line
        on = [k for k in distinct if k in (i, j) or _degenerate(pts[i], pts[j], pts[k], tol)]
        best = max(best, on, key=len)
    return (f"points {', '.join(str(k + 1) for k in best)} lie on one line"
            + (f" and only point {(set(distinct) - set(best)).pop() + 1} is off it"
               if len(best) == len(distinct) - 1 else ""))


def _pair(where: str, value: Any) -> list[float]:
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            or not all(math.isfinite(v) for v in value)):
        raise InputError(f"{where} must be two finite numbers [a, b]")
    return [float(v) for v in value]


def parse_calibration(data: dict[str, Any], source: str) -> Calibration:
    """Validate parsed CALIB.toml content and fit the homography (InputError naming `source`)."""
    unknown = set(data) - {"points", "frame_size"}
    if unknown:
        raise InputError(f"{source}: unknown key {sorted(unknown)[0]!r} (known: points, "
                         f"frame_size)")
    points = data.get("points")
    if not isinstance(points, list) or not all(isinstance(p, dict) for p in points):
        raise InputError(f"{source}: needs [[points]] tables with image = [u, v] and "
                         f"world = [X, Y]")
    if len(points) < 4:
        raise InputError(f"{source}: needs at least 4 [[points]], has {len(points)}")
    image, world = [], []
    for k, p in enumerate(points, 1):
        extra = set(p) - {"image", "world"}
        if extra or not {"image", "world"} <= set(p):
            raise InputError(f"{source}: point {k} must have exactly image = [u, v] and "
                             f"world = [X, Y]")
        image.append(_pair(f"{source}: point {k} image", p["image"]))
        world.append(_pair(f"{source}: point {k} world", p["world"]))
    image_a, world_a = np.array(image), np.array(world)
    if general_quadruple([image_a, world_a]) is None:
        for name, pts in (("image", image_a), ("world", world_a)):
            if general_quadruple([pts]) is None:
                raise InputError(f"{source}: the points fix no homography: no 4 of the "
                                 f"{len(pts)} are in general position in {name} coordinates "
                                 f"({why_degenerate(pts)}; 4 with no 3 on a line are needed)")
        raise InputError(f"{source}: the points fix no homography: no 4 of them are in "
                         f"general position in both image and world coordinates (4 with no 3 "
                         f"on a line in both are needed)")
    size = data.get("frame_size")
    if size is not None:
        if (not isinstance(size, list) or len(size) != 2
                or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0
                           for v in size)):
            raise InputError(f"{source}: frame_size must be two positive integers [W, H]")
        size = (size[0], size[1])
    try:
        H = fit_homography(image_a, world_a)
    except ValueError as exc:
        raise InputError(f"{source}: the points fix no homography: {exc}") from None
    w = image_a @ H[2, :2] + H[2, 2]
    if not (np.all(w > 0) or np.all(w < 0)):
        raise InputError(f"{source}: the points lie on both sides of the road plane's horizon "
                         f"(image and world points do not correspond)")
    return Calibration(H, image_a, world_a, size, source)


def load_calibration(path: str | Path) -> Calibration:
    """Read and fit CALIB.toml; any problem is an InputError naming the file."""
    return parse_calibration(read_toml(path), str(path))
