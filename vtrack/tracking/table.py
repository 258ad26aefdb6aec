"""The track table: every track's state as parallel arrays (one row a track), so that the
roles work on all tracks at once. Each role owns its columns -- their layout, the values a
new track starts with, how they move with the camera -- in its own module:

- centre (filter_bank.CentreColumns): x, P, the centre filter's state;
- history (measurements.HistoryColumns): hist_p, hist_t, hist_s, count, the last three
  detected centres the centre measurement differences;
- box_size (sizes.SizeColumns): s, Ps, mismatch_t, mismatch_sign, own, ref_p, ref_s, the
  box size filter's state, the own-size memory and the scale field's reference;
- life (lifecycle.LifeColumns): origin, last_box, hitmask, standing, id, uid, dup_t,
  seen, the lifecycle's record;
- reid (reidentifier.ReidColumns): born, v_seen, colour, what re-identifies a track's
  vehicle once it is lost.

(The associator's fragment stage keeps its gap record apart, fragments.GapColumns.) The
table reads and writes each column by its name (`tracks.x` is `tracks.centre.x`); `keep`,
`append` and `warp` act on every group together.
"""

from __future__ import annotations

from dataclasses import dataclass
from operator import attrgetter
from typing import get_type_hints

import numpy as np

from vtrack.boxes import clip, from_centre
from vtrack.tracking.columns import Columns
from vtrack.tracking.filter_bank import CentreColumns
from vtrack.tracking.lifecycle import LifeColumns
from vtrack.tracking.measurements import HistoryColumns
from vtrack.tracking.reidentifier import ReidColumns
from vtrack.tracking.sizes import SizeColumns


@dataclass
class TrackTable:
    """The roles' columns over the same tracks (module docstring)."""

    centre: CentreColumns
    history: HistoryColumns
    box_size: SizeColumns
    life: LifeColumns
    reid: ReidColumns

    @classmethod
    def empty(cls) -> TrackTable:
        """A table without tracks."""
        return cls(CentreColumns.empty(), HistoryColumns.empty(), SizeColumns.empty(),
                   LifeColumns.empty(), ReidColumns.empty())

    def groups(self) -> list[Columns]:
        """The role groups, in field order."""
        return [self.centre, self.history, self.box_size, self.life, self.reid]

    def __len__(self) -> int:
        return len(self.centre)

    def keep(self, mask: np.ndarray) -> None:
        """Drop the tracks where `mask` is False."""
        for g in self.groups():
            g.keep(mask)

    def append(self, other: TrackTable) -> None:
        """Add the tracks of `other` at the end."""
        for g, o in zip(self.groups(), other.groups(), strict=True):
            g.append(o)

    def warp(self, m: np.ndarray) -> None:
        """Move every track with the camera: m (2, 3) maps the previous frame's pixels onto
        the current frame's (each group's `warp`)."""
        for g in self.groups():
            g.warp(m)

    @property
    def size(self) -> np.ndarray:
        """(N, 2) box width and height, px."""
        return np.exp(self.s[:, :2])

    @property
    def scale(self) -> np.ndarray:
        """(N,) box scale sqrt(w h), px: the unit of the scale-free parameters."""
        return np.exp(self.s[:, :2].mean(axis=1))

    @property
    def confirmed(self) -> np.ndarray:
        """Indices of the confirmed tracks."""
        return np.flatnonzero(self.id > 0)

    def boxes(self, width: int, height: int) -> np.ndarray:
        """Boxes (x, y, w, h) centred on the filtered positions, clipped to the image."""
        return clip(from_centre(self.x[:, :2], self.size), width, height)


def _column(group: str, name: str) -> property:
    get = attrgetter(f"{group}.{name}")   # read on every use: C, not a Python frame

    def put(self: TrackTable, value: np.ndarray) -> None:
        setattr(getattr(self, group), name, value)

    return property(get, put, doc=f"`{group}.{name}`")


# Each group's columns by name on the table (tracks.x is tracks.centre.x).
for _group, _cls in get_type_hints(TrackTable).items():
    for _name in _cls.LAYOUT:
        setattr(TrackTable, _name, _column(_group, _name))
