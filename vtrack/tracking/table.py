"""The track table: every track's state and bookkeeping as parallel arrays (one row a track),
so that the filter bank, the associator and the lifecycle work on all tracks at once."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, ClassVar, Self

import numpy as np

from vtrack.boxes import clip, from_centre

OWN = 9  # detections whose median gives a vehicle's own size (box_size.py)


class Columns:
    """Per-track columns (a struct of arrays, one row a track) owned by one role: the role
    gives new rows their initial values and moves them with the camera (`warp`); the
    tracker keeps every role's rows in step (`keep`, `append`). A subclass is a dataclass
    of arrays whose shapes and dtypes per track are its LAYOUT."""

    LAYOUT: ClassVar[dict[str, tuple[tuple[int, ...], Any]]] = {}

    @classmethod
    def empty(cls) -> Self:
        """No rows."""
        return cls(**{name: np.zeros((0,) + shape, dtype=dtype)
                      for name, (shape, dtype) in cls.LAYOUT.items()})

    def __len__(self) -> int:
        return len(getattr(self, next(iter(self.LAYOUT))))

    def keep(self, mask: np.ndarray) -> None:
        """Drop the rows where `mask` is False."""
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name)[mask])

    def append(self, other: Self) -> None:
        """Add the rows of `other` at the end."""
        for f in fields(self):
            setattr(self, f.name, np.concatenate([getattr(self, f.name),
                                                  getattr(other, f.name)]))

    def copy(self) -> Self:
        """An independent copy."""
        return type(self)(**{f.name: getattr(self, f.name).copy() for f in fields(self)})


@dataclass
class TrackTable(Columns):
    """Struct of arrays over tracks; `keep` and `append` act on every column together."""

    x: np.ndarray          # (N, 6) filtered [x, y, vx, vy, ax, ay] of the box centre
    P: np.ndarray          # (N, 6, 6) its covariance
    s: np.ndarray          # (N, 4) [ln w, ln h, d ln w/dt, d ln h/dt] of the box (box_size.py)
    Ps: np.ndarray         # (N, 4, 4) its covariance
    mismatch_t: np.ndarray     # (N, 2) since when detections disagree with the size
    mismatch_sign: np.ndarray  # (N, 2) in which direction (+1 larger, -1 smaller, 0 none)
    ref_p: np.ndarray      # (N, 2) a whole-vehicle box's centre kept for the scale field
    ref_s: np.ndarray      # (N,) and its scale (nan: none yet)
    own: np.ndarray        # (N, OWN, 2) ln((w, h) / k) of the last detections (nan: none)
    origin: np.ndarray     # (N, 4) the first detected box's edges x0, y0, x1, y1
    last_box: np.ndarray   # (N, 4) the last detected box's edges
    hist_p: np.ndarray     # (N, 3, 2) last three detected centres, newest first
    hist_t: np.ndarray     # (N, 3) their times
    hist_s: np.ndarray     # (N, 3, 2) their stds
    count: np.ndarray      # (N,) detections so far, capped at 3 (for the differences)
    hitmask: np.ndarray    # (N,) bit i: detected i frames ago
    standing: np.ndarray   # (N,) a standing vehicle held without detections (lifecycle.py)
    id: np.ndarray         # (N,) public id, 0 while tentative
    uid: np.ndarray        # (N,) internal id, unique for the run

    LAYOUT: ClassVar[dict[str, tuple[tuple[int, ...], Any]]] = {
        "x": ((6,), float), "P": ((6, 6), float), "s": ((4,), float), "Ps": ((4, 4), float),
        "mismatch_t": ((2,), float), "mismatch_sign": ((2,), float), "ref_p": ((2,), float),
        "ref_s": ((), float), "own": ((OWN, 2), float), "origin": ((4,), float),
        "last_box": ((4,), float), "hist_p": ((3, 2), float),
        "hist_t": ((3,), float), "hist_s": ((3, 2), float), "count": ((), int),
        "hitmask": ((), np.int64), "standing": ((), bool), "id": ((), int), "uid": ((), int),
    }

    @property
    def size(self) -> np.ndarray:
        """(N, 2) box width and height, px."""
        return np.exp(self.s[:, :2])

    @property
    def scale(self) -> np.ndarray:
        """(N,) box scale sqrt(w h), px: the unit of the scale-free parameters."""
        return np.exp(self.s[:, :2].mean(axis=1))

    def warp(self, m: np.ndarray) -> None:
        """Move every track with the camera: m (2, 3) maps the previous frame's pixels onto
        the current frame's (p' = A p + b). Positions map by m; velocities, accelerations
        and the covariance by A (P' = T P T', T = I3 (x) A); sizes scale by sqrt|det A|."""
        A, b = m[:, :2], m[:, 2]
        T = np.zeros((6, 6))
        T[0:2, 0:2] = T[2:4, 2:4] = T[4:6, 4:6] = A
        self.x = self.x @ T.T
        self.x[:, :2] += b
        self.P = T @ self.P @ T.T
        scale = float(np.sqrt(abs(np.linalg.det(A))))
        self.s[:, :2] += np.log(scale)
        self.own += np.log(scale)
        self.hist_s = self.hist_s * scale
        for edges in (self.origin, self.last_box):  # corners moved (boxes stay axis-aligned)
            edges[:, :2] = edges[:, :2] @ A.T + b
            edges[:, 2:] = edges[:, 2:] @ A.T + b
        self.hist_p = self.hist_p @ A.T + b

    @property
    def confirmed(self) -> np.ndarray:
        """Indices of the confirmed tracks."""
        return np.flatnonzero(self.id > 0)

    def boxes(self, width: int, height: int) -> np.ndarray:
        """Boxes (x, y, w, h) centred on the filtered positions, clipped to the image."""
        return clip(from_centre(self.x[:, :2], self.size), width, height)

