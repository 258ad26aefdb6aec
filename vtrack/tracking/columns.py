"""Per-track columns: the rows of one role's state, one row a track, kept in step with
every other role's by the tracker (the track table, table.py, joins them)."""

from __future__ import annotations

from typing import Any, ClassVar, Self

import numpy as np


class Columns:
    """Per-track columns (a struct of arrays, one row a track) owned by one role: the role
    gives new rows their initial values and moves them with the camera (`warp`); the
    tracker keeps every role's rows in step (`keep`, `append`). A subclass is a dataclass
    of arrays whose shapes and dtypes per track are its LAYOUT (its fields, in order)."""

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
        for name in self.LAYOUT:
            setattr(self, name, getattr(self, name)[mask])

    def append(self, other: Self) -> None:
        """Add the rows of `other` at the end."""
        for name in self.LAYOUT:
            setattr(self, name, np.concatenate([getattr(self, name), getattr(other, name)]))

    def copy(self) -> Self:
        """An independent copy."""
        return type(self)(**{name: getattr(self, name).copy() for name in self.LAYOUT})

    def warp(self, m: np.ndarray) -> None:
        """Move the rows with the camera: m (2, 3) maps the previous frame's pixels onto the
        current frame's (p' = A p + b). Columns that hold no image geometry stay."""


def warp_scale(m: np.ndarray) -> float:
    """sqrt|det A| of a camera motion m (2, 3): how much it scales image sizes."""
    return float(np.sqrt(abs(np.linalg.det(m[:, :2]))))
