"""The road plane of a scene as data: straight strips of asphalt with their painted markings,
the verges beside them, and the far scenery where the modelled ground ends."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

WHITE = (222, 226, 226)
YELLOW = (40, 185, 222)


@dataclass(frozen=True)
class Marking:
    """A painted line along a strip at `offset` (m, left of the strip's axis), solid when
    `dash` is 0, else dashes of `dash` m every `period` m starting at `phase`."""

    offset: float
    width: float
    dash: float = 0.0
    period: float = 1.0
    phase: float = 0.0
    colour: tuple[int, int, int] = WHITE


@dataclass(frozen=True)
class Strip:
    """A straight stretch of road: its axis starts at `origin` with `heading`; the asphalt
    covers along in [start, end] and across in [right, left] (m, left positive)."""

    origin: tuple[float, float]
    heading: float
    start: float
    end: float
    right: float
    left: float
    lanes: tuple[float, ...] = ()                          # lane centres (across, m)
    markings: tuple[Marking, ...] = ()
    bars: tuple[tuple[float, float, float, float], ...] = ()   # stop lines: along0, along1,
    zebras: tuple[tuple[float, float, float, float], ...] = ()  # across0, across1 (same)

    def local(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(along, across) coordinates of world points."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        dx, dy = x - self.origin[0], y - self.origin[1]
        return dx * c + dy * s, -dx * s + dy * c

    def world(self, along: float, across: float) -> tuple[float, float]:
        """World (x, y) of a point given in strip coordinates."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        return (self.origin[0] + along * c - across * s, self.origin[1] + along * s + across * c)


@dataclass(frozen=True)
class Ground:
    """Everything painted on the road plane and beyond it."""

    strips: tuple[Strip, ...]
    asphalt: tuple[float, float, float]       # BGR
    verge: str                                # "grass" (rural) or "pavement" (urban)
    verge_colour: tuple[float, float, float]
    pavement_m: float                         # width of the pavement beside the asphalt
    far_m: float                              # the ground ends (tree line, hills) this far
    sky: tuple[float, float, float]
    treeline: tuple[float, float, float]
    patches: tuple[tuple[float, float, float, float, float, float], ...] = ()
    # repaired asphalt: centre x, y, length, width, heading, brightness factor
