"""The track table: every track's state and bookkeeping as parallel arrays (one row a track),
so that the filter bank, the associator and the lifecycle work on all tracks at once."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np


@dataclass
class TrackTable:
    """Struct of arrays over tracks; `keep` and `append` act on every column together."""

    x: np.ndarray          # (N, 6) filtered [x, y, vx, vy, ax, ay] of the box centre
    P: np.ndarray          # (N, 6, 6) its covariance
    size: np.ndarray       # (N, 2) box width and height, px
    origin: np.ndarray     # (N, 2) the first detected centre
    hist_p: np.ndarray     # (N, 3, 2) last three detected centres, newest first
    hist_t: np.ndarray     # (N, 3) their times
    hist_s: np.ndarray     # (N, 3, 2) their stds (see measurements.nested_centre)
    count: np.ndarray      # (N,) detections so far, capped at 3 (for the differences)
    hitmask: np.ndarray    # (N,) bit i: detected i frames ago
    misses: np.ndarray     # (N,) frames since the last detection
    killed: np.ndarray     # (N,) a duplicate of an older track, deleted this frame
    id: np.ndarray         # (N,) public id, 0 while tentative
    uid: np.ndarray        # (N,) internal id, unique for the run
    gap_p: np.ndarray      # (N, 2) where a gap between two pieces was first seen
    gap_t: np.ndarray      # (N,) and when (nan: the track's box holds one piece)

    @classmethod
    def empty(cls) -> TrackTable:
        """A table without tracks."""
        return cls(**{f.name: np.zeros((0,) + shape, dtype=dtype)
                      for f, (shape, dtype) in zip(fields(cls), _LAYOUT, strict=True)})

    def __len__(self) -> int:
        return len(self.x)

    def keep(self, mask: np.ndarray) -> None:
        """Drop the tracks where `mask` is False."""
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name)[mask])

    def append(self, other: TrackTable) -> None:
        """Add the tracks of `other` at the end."""
        for f in fields(self):
            setattr(self, f.name, np.concatenate([getattr(self, f.name),
                                                  getattr(other, f.name)]))

    @property
    def confirmed(self) -> np.ndarray:
        """Indices of the confirmed tracks."""
        return np.flatnonzero(self.id > 0)

    def boxes(self, width: int, height: int) -> np.ndarray:
        """Boxes (x, y, w, h) centred on the filtered positions, clipped to the image."""
        half = self.size / 2
        x0 = np.clip(self.x[:, 0] - half[:, 0], 0, width)
        y0 = np.clip(self.x[:, 1] - half[:, 1], 0, height)
        x1 = np.clip(self.x[:, 0] + half[:, 0], 0, width)
        y1 = np.clip(self.x[:, 1] + half[:, 1], 0, height)
        return np.stack([x0, y0, x1 - x0, y1 - y0], axis=1)


_LAYOUT = (((6,), float), ((6, 6), float), ((2,), float), ((2,), float), ((3, 2), float),
           ((3,), float), ((3, 2), float), ((), int), ((), np.int64), ((), int), ((), bool),
           ((), int), ((), int), ((2,), float), ((), float))
