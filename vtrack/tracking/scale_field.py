"""The scene's scale field: how big a vehicle looks at each place in the image.

A camera on a pole or a bridge sees the road in perspective: one vehicle's image size
changes several times between the far and the near end. For a road plane under a pinhole
camera the image size of a vehicle is close to linear in its image position,

    s = m k(x, y),   k(x, y) = theta . (1, x/W, y/H),

with m the vehicle's own size and k the scene's scale, known up to a constant factor. Two
whole-vehicle boxes of one track at p1, p2 (sizes s1, s2) share m, so theta is orthogonal to

    r = sqrt(s1 s2) (u(p1) / s1 - u(p2) / s2),   u(p) = (1, x/W, y/H),

and theta is the eigenvector of the smallest eigenvalue of sum r r' (plus a small pull
toward the flat field theta = (1, 0, 0), which is what an overhead camera has and what too
few pairs leave). The tracker uses the field's gradient to predict how each box grows or
shrinks as its vehicle moves (d ln s / dt = grad ln k . v), so a box that shrinks because an
occluder covers it -- not because the vehicle drives away -- no longer fits the size filter,
and the field tells a detection the size of a whole vehicle at its place from a fragment or
a merge of several.
"""

from __future__ import annotations

import numpy as np

FLAT_PRIOR = 0.5   # weight of the pull toward the flat field, in pairs


class ScaleField:
    """k(x, y) learnt online from pairs of whole-vehicle boxes of one track."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.M = np.zeros((3, 3))
        self.pairs = 0
        self.theta = np.array([1.0, 0.0, 0.0])

    def _u(self, p: np.ndarray) -> np.ndarray:
        return np.column_stack([np.ones(len(p)), p[:, 0] / self.width, p[:, 1] / self.height])

    def add(self, p1: np.ndarray, s1: np.ndarray, p2: np.ndarray, s2: np.ndarray) -> None:
        """Add pairs of observations (positions (K, 2), box scales (K,)) of K vehicles."""
        if len(p1) == 0:
            return
        r = np.sqrt(s1 * s2)[:, None] * (self._u(p1) / s1[:, None] - self._u(p2) / s2[:, None])
        self.M += r.T @ r
        self.pairs += len(r)
        _, vecs = np.linalg.eigh(self.M + FLAT_PRIOR * np.diag([0.0, 1.0, 1.0]))
        theta = vecs[:, 0]
        corners = self._u(np.array([[0, 0], [self.width, 0], [0, self.height],
                                    [self.width, self.height]], dtype=float)) @ theta
        self.theta = theta * np.sign(corners.sum() or 1.0)

    def k(self, p: np.ndarray) -> np.ndarray:
        """The relative scale at positions p (K, 2), floored at 5 % of its image maximum
        (beyond the horizon a linear field would turn negative)."""
        corners = self._u(np.array([[0, 0], [self.width, 0], [0, self.height],
                                    [self.width, self.height]], dtype=float)) @ self.theta
        return np.maximum(self._u(p) @ self.theta, 0.05 * corners.max())

    def log_rate(self, p: np.ndarray, v: np.ndarray) -> np.ndarray:
        """d ln s / dt (K,) of vehicles at p (K, 2) moving with image velocity v (K, 2)."""
        grad = np.array([self.theta[1] / self.width, self.theta[2] / self.height])
        return (v @ grad) / self.k(p)
