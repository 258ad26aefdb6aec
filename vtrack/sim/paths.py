"""Vehicle paths on the road plane: chains of pieces of constant curvature (lines and arcs).

A piece starting at (x0, y0) with heading th0 and curvature k reaches, after arc length t,

    line (k = 0):  (x0 + t cos th0,  y0 + t sin th0),                          heading th0
    arc:           (x0 + (sin(th0 + k t) - sin th0) / k,
                    y0 - (cos(th0 + k t) - cos th0) / k),                       heading th0 + k t

Pieces join with a common tangent. Before its start and after its end a path continues as a
straight line (vehicles enter and leave off-screen). `PathSet` holds every path of a scene in
padded arrays so that poses and projections are evaluated for all vehicles at once.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Path:
    """Start pose and the (curvature 1/m, length m) of each piece."""

    x: float
    y: float
    heading: float
    pieces: tuple[tuple[float, float], ...]

    @classmethod
    def line(cls, start: Sequence[float], end: Sequence[float]) -> Path:
        """The straight path from `start` to `end` (x, y)."""
        dx, dy = end[0] - start[0], end[1] - start[1]
        return cls(float(start[0]), float(start[1]), math.atan2(dy, dx),
                   ((0.0, math.hypot(dx, dy)),))

    @classmethod
    def turn(cls, start: Sequence[float], corner: Sequence[float], end: Sequence[float],
             radius: float) -> Path:
        """Straight from `start` towards `corner`, a circular arc of `radius` tangent to both
        legs, straight on to `end` (tangent length radius * tan(|turn| / 2))."""
        a = math.atan2(corner[1] - start[1], corner[0] - start[0])
        b = math.atan2(end[1] - corner[1], end[0] - corner[0])
        turn = math.remainder(b - a, 2 * math.pi)
        tangent = radius * math.tan(abs(turn) / 2)
        leg_in = math.hypot(corner[0] - start[0], corner[1] - start[1]) - tangent
        leg_out = math.hypot(end[0] - corner[0], end[1] - corner[1]) - tangent
        if min(leg_in, leg_out) < 0:
            raise ValueError("turn radius too large for its legs")
        arc = (math.copysign(1 / radius, turn), radius * abs(turn))
        return cls(float(start[0]), float(start[1]), a, ((0.0, leg_in), arc, (0.0, leg_out)))

    @classmethod
    def shift(cls, start: Sequence[float], heading: float, before: float, offset: float,
              transition: float, after: float) -> Path:
        """Straight for `before` m, then an S of two opposite arcs that moves `offset` m to
        the left (negative: right) over `transition` m, then straight for `after` m. Arcs of
        angle a and radius r: offset = 2 r (1 - cos a), transition = 2 r sin a, so
        tan(a / 2) = |offset| / transition."""
        a = 2 * math.atan(abs(offset) / transition)
        r = transition / (2 * math.sin(a))
        k = math.copysign(1 / r, offset)
        return cls(float(start[0]), float(start[1]), heading,
                   ((0.0, before), (k, r * a), (-k, r * a), (0.0, after)))

    @property
    def length(self) -> float:
        """Total arc length (m)."""
        return sum(length for _, length in self.pieces)


def _advance(x: np.ndarray, y: np.ndarray, th: np.ndarray, k: np.ndarray,
             t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pose after arc length t along pieces (x, y, th, k) (module docstring)."""
    straight = np.abs(k) < 1e-12
    ks = np.where(straight, 1.0, k)
    th1 = th + k * t
    xa = x + (np.sin(th1) - np.sin(th)) / ks
    ya = y - (np.cos(th1) - np.cos(th)) / ks
    return (np.where(straight, x + t * np.cos(th), xa),
            np.where(straight, y + t * np.sin(th), ya), th1)


class PathSet:
    """All paths of a scene as (paths, pieces) arrays, padded with empty pieces."""

    def __init__(self, paths: Sequence[Path]) -> None:
        self.paths = tuple(paths)
        q = max(len(p.pieces) for p in self.paths)
        shape = (len(self.paths), q)
        self.k, self.len = np.zeros(shape), np.zeros(shape)
        self.valid = np.zeros(shape, dtype=bool)
        for i, p in enumerate(self.paths):
            for j, (k, length) in enumerate(p.pieces):
                self.k[i, j], self.len[i, j], self.valid[i, j] = k, length, True
        self.count = np.array([len(p.pieces) for p in self.paths])
        self.s0 = np.concatenate([np.zeros((shape[0], 1)), np.cumsum(self.len, 1)[:, :-1]], 1)
        self.total = self.len.sum(1)
        self.x0, self.y0, self.th0 = np.zeros(shape), np.zeros(shape), np.zeros(shape)
        x = np.array([p.x for p in self.paths])
        y = np.array([p.y for p in self.paths])
        th = np.array([p.heading for p in self.paths])
        for j in range(q):
            self.x0[:, j], self.y0[:, j], self.th0[:, j] = x, y, th
            x, y, th = _advance(x, y, th, self.k[:, j], self.len[:, j])

    def pose(self, path: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (..., 2) and headings (...) at arc lengths s on paths `path` (same shape);
        straight extensions before the start and after the end."""
        path, s = np.broadcast_arrays(np.asarray(path), np.asarray(s, float))
        piece = (s[..., None] >= self.s0[path]).sum(-1) - 1
        piece = np.clip(piece, 0, self.count[path] - 1)
        t = s - self.s0[path, piece]
        k = self.k[path, piece]
        before = (piece == 0) & (t < 0)
        k = np.where(before, 0.0, k)
        last_len = self.len[path, piece]
        after = (piece == self.count[path] - 1) & (t > last_len)
        x, y, th = _advance(self.x0[path, piece], self.y0[path, piece], self.th0[path, piece],
                            k, np.where(after, last_len, t))
        extra = np.where(after, t - last_len, 0.0)
        x, y = x + extra * np.cos(th), y + extra * np.sin(th)
        return np.stack([x, y], -1), th

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Arc length s (paths, N) of the nearest point of each path to each of N points
        (2,), and the signed lateral offset (positive to the left of the path)."""
        p = np.asarray(points, float)
        px, py = p[None, None, :, 0], p[None, None, :, 1]
        x0, y0, th, k, length = (a[:, :, None] for a in (self.x0, self.y0, self.th0, self.k,
                                                        self.len))
        straight = np.abs(k) < 1e-12
        ks = np.where(straight, 1.0, k)
        # lines
        c, s = np.cos(th), np.sin(th)
        wx, wy = px - x0, py - y0
        t_line, lat_line = wx * c + wy * s, c * wy - s * wx
        # arcs: centre to the left (k > 0) or right (k < 0) of the start
        cx, cy = x0 - s / ks, y0 + c / ks
        phi = np.arctan2(py - cy, px - cx) - np.arctan2(y0 - cy, x0 - cx)
        dphi = np.remainder(phi + np.pi, 2 * np.pi) - np.pi
        t_arc = dphi / ks
        lat_arc = np.sign(ks) * (1 / np.abs(ks) - np.hypot(px - cx, py - cy))
        t = np.where(straight, t_line, t_arc)
        lat = np.where(straight, lat_line, lat_arc)
        q = np.arange(self.k.shape[1])[None, :, None]
        lo = np.where(q == 0, -np.inf, 0.0)
        hi = np.where(q == self.count[:, None, None] - 1, np.inf, length)
        tc = np.clip(t, lo, hi)
        ex, ey, _ = _advance(x0, y0, th, k, np.clip(tc, 0, length))
        ex = ex + (tc - np.clip(tc, 0, length)) * np.cos(th + k * np.clip(tc, 0, length))
        ey = ey + (tc - np.clip(tc, 0, length)) * np.sin(th + k * np.clip(tc, 0, length))
        gap = np.hypot(px - ex, py - ey)
        lat = np.where(tc == t, lat, np.copysign(gap, lat))
        dist = np.where(self.valid[:, :, None], gap, np.inf)
        best = np.argmin(dist, axis=1)[:, None, :]
        s_out = np.take_along_axis(self.s0[:, :, None] + tc, best, 1)[:, 0]
        lat_out = np.take_along_axis(lat, best, 1)[:, 0]
        return s_out, lat_out
