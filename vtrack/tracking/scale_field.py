"""The scene's scale field: how big a vehicle looks at each place in the image.

A camera on a pole or a bridge sees the road in perspective: one vehicle's image size
changes several times between the far and the near end. For a road plane under a pinhole
camera the image size of a vehicle is close to linear in its image position,

    s = m k(x, y),   k(x, y) = 1 + b x/W + c y/H,

with m the vehicle's own size and k the scene's relative scale. Two whole-vehicle boxes of
one track at p1, p2 (sizes s1, s2) share m, so

    ln(s2 / s1) = ln k(p2) - ln k(p1),

and (b, c) are fitted to the last `MEMORY` such pairs by Gauss-Newton with Cauchy weights
(a pair spoilt by a merge or an occluder weighs little) and a small ridge toward the flat
field b = c = 0, which is what an overhead camera has and what the pairs leave undetermined
(the field across the road when vehicles only drive along it). The field is used from
`MIN_PAIRS` pairs on, the flat field until then. The tracker predicts each box's growth from
its motion, d ln s / dt = grad ln k . v (capped at `MAX_LOG_RATE`), so a box that shrinks
because an occluder covers it -- not because the vehicle drives away -- no longer fits the
size filter.
"""

from __future__ import annotations

from collections import deque

import numpy as np

RIDGE = 0.01         # weight of the pull toward the flat field
MEMORY = 1000        # pairs kept for the fit
MIN_PAIRS = 20       # pairs before the field is used
MAX_LOG_RATE = 1.0   # largest |d ln s/dt| the field predicts, 1/s
REFIT_EVERY = 10     # pairs between fits


class ScaleField:
    """k(x, y) learnt online from pairs of whole-vehicle boxes of one track."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self._pairs: deque[np.ndarray] = deque(maxlen=MEMORY)  # x1, y1, x2, y2, ln(s2/s1)
        self.pairs = 0
        self._fitted = 0
        self.bc = np.zeros(2)

    def _norm(self, p: np.ndarray) -> np.ndarray:
        return p / np.array([self.width, self.height])

    def add(self, p1: np.ndarray, s1: np.ndarray, p2: np.ndarray, s2: np.ndarray) -> None:
        """Add pairs of observations (positions (K, 2), box scales (K,)) of K vehicles."""
        if len(p1) == 0:
            return
        self._pairs.extend(np.column_stack([self._norm(p1), self._norm(p2), np.log(s2 / s1)]))
        self.pairs += len(p1)
        if self.pairs >= MIN_PAIRS and self.pairs - self._fitted >= REFIT_EVERY:
            self.bc = self._fit(np.array(self._pairs))
            self._fitted = self.pairs

    @staticmethod
    def _fit(d: np.ndarray) -> np.ndarray:
        """(b, c) by robust Gauss-Newton (module docstring)."""
        u1, u2, y = d[:, 0:2], d[:, 2:4], d[:, 4]
        bc = np.zeros(2)
        for _ in range(200):
            k1, k2 = np.maximum(1 + u1 @ bc, 0.05), np.maximum(1 + u2 @ bc, 0.05)
            e = y - (np.log(k2) - np.log(k1))
            J = u2 / k2[:, None] - u1 / k1[:, None]          # d(model)/d(b, c)
            scale = 1.4826 * np.median(np.abs(e)) + 1e-3
            w = 1.0 / (1.0 + (e / (2.0 * scale)) ** 2)
            A = (J * w[:, None]).T @ J + RIDGE * np.eye(2)
            step = np.linalg.solve(A, (J * w[:, None]).T @ e - RIDGE * bc)
            bc = bc + step
            if np.abs(step).max() < 1e-6:
                break
        return bc

    def k(self, p: np.ndarray) -> np.ndarray:
        """The relative scale at positions p (K, 2), floored at 5 % (beyond the horizon a
        linear field would turn negative)."""
        return np.maximum(1 + self._norm(p) @ self.bc, 0.05)

    def log_rate(self, p: np.ndarray, v: np.ndarray) -> np.ndarray:
        """d ln s / dt (K,) of vehicles at p (K, 2) moving with image velocity v (K, 2)."""
        grad = self.bc / np.array([self.width, self.height])
        return np.clip((v @ grad) / self.k(p), -MAX_LOG_RATE, MAX_LOG_RATE)
