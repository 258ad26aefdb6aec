"""Counting lines and zones as the user gives them: in pixels or in fractions of the image,
optionally named; converted to pixels once the video's size is known.

    count_lines = [[x1, y1, x2, y2], {name = "north", points = [[0, 0.6], [1, 0.6]],
                                      units = "fraction"}]
    [[zones]]
    name = "stop-line"
    polygon = [[0.1, 0.7], [0.5, 0.7], [0.5, 0.8], [0.1, 0.8]]
    units = "fraction"            # "px" by default
    debounce_s = 0.2              # optional
    roi = [[0.0, 0.4], [1.0, 0.4], [1.0, 1.0], [0.0, 1.0]]   # region of interest (top level)
    roi_units = "fraction"        # "px" by default
    [[gates]]                     # where vehicles enter and leave (turning movements)
    name = "north"
    line = [[0.4, 0.0], [0.6, 0.0]]   # or polygon = [[x, y], ...]
    units = "fraction"

A fraction f of the width W is the pixel coordinate f * W (0 is the left edge of the image,
1 its right edge), likewise for the height.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from vtrack.errors import InputError

UNITS = ("px", "fraction")
ZONE_DEBOUNCE_S = 0.2


def _scale(points: Sequence[Sequence[float]], units: str, width: int, height: int
           ) -> np.ndarray:
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    return pts * (width, height) if units == "fraction" else pts


@dataclass(frozen=True)
class CountLine:
    """A counting segment (two points), in `units`, optionally named."""

    points: tuple[tuple[float, float], tuple[float, float]]
    units: str = "px"
    name: str | None = None

    def pixels(self, width: int, height: int) -> list[float]:
        """[x1, y1, x2, y2] in pixels of a width x height image."""
        return [float(v) for v in _scale(self.points, self.units, width, height).ravel()]


@dataclass(frozen=True)
class Zone:
    """A polygon zone, in `units`, with the time a change of inside/outside must persist."""

    name: str
    polygon: tuple[tuple[float, float], ...]
    units: str = "px"
    debounce_s: float = field(default=ZONE_DEBOUNCE_S, metadata={
        "help": "a vehicle is in (or out of) the zone once its ground point has stayed in "
                "(or out) this long, s; the event is dated from the first frame of the stay"})

    def pixels(self, width: int, height: int) -> np.ndarray:
        """(n, 2) vertices in pixels of a width x height image."""
        return _scale(self.polygon, self.units, width, height)


@dataclass(frozen=True)
class Gate:
    """A named gate of the turning movements: a segment (`line`, two points) or a polygon
    (`polygon`, 3+ vertices), in `units`."""

    name: str
    line: tuple[tuple[float, float], tuple[float, float]] | None = None
    polygon: tuple[tuple[float, float], ...] | None = None
    units: str = "px"

    def pixels(self, width: int, height: int) -> np.ndarray:
        """(2, 2) segment ends or (n, 2) polygon vertices in pixels."""
        return _scale(self.line if self.line is not None else self.polygon, self.units,
                      width, height)


@dataclass(frozen=True)
class Roi:
    """The region of interest: the detector sees only what lies inside this polygon."""

    polygon: tuple[tuple[float, float], ...]
    units: str = "px"

    def pixels(self, width: int, height: int) -> np.ndarray:
        """(n, 2) vertices in pixels of a width x height image."""
        return _scale(self.polygon, self.units, width, height)


def _numbers(where: str, value: Any, n: int | None = None) -> list[float]:
    if (not isinstance(value, (list, tuple)) or (n is not None and len(value) != n)
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            or not all(math.isfinite(v) for v in value)):
        what = f"{n} finite numbers" if n else "finite numbers"
        raise InputError(f"{where}: expected {what}")
    return [float(v) for v in value]


def _points(where: str, value: Any) -> list[tuple[float, float]]:
    if not isinstance(value, list) or not value:
        raise InputError(f"{where}: expected a list of [x, y] points")
    return [tuple(_numbers(f"{where} point {k + 1}", p, 2)) for k, p in enumerate(value)]


def _units(where: str, value: Any, points: Sequence[Sequence[float]]) -> str:
    if value not in UNITS:
        raise InputError(f"{where}: units must be \"px\" or \"fraction\", not {value!r}")
    if value == "fraction" and not all(0.0 <= v <= 1.0 for p in points for v in p):
        raise InputError(f"{where}: fractions of the image must be within 0..1")
    return value


def _name(where: str, value: Any) -> str:
    if not isinstance(value, str) or not value.strip() or value.strip().isdigit():
        raise InputError(f"{where}: name must be a non-empty string that is not a number")
    if any(c in value for c in ",\n\r\""):
        raise InputError(f"{where}: name {value!r} must not contain commas, quotes or newlines")
    return value.strip()


def _table(where: str, value: dict, keys: set[str], required: set[str]) -> None:
    unknown = set(value) - keys
    if unknown:
        raise InputError(f"{where}: unknown key {sorted(unknown)[0]!r} "
                         f"(known: {', '.join(sorted(keys))})")
    missing = required - set(value)
    if missing:
        raise InputError(f"{where}: missing {sorted(missing)[0]!r}")


def parse_count_line(where: str, value: Any) -> CountLine:
    """[x1, y1, x2, y2] (pixels) or {name, points = [[x1, y1], [x2, y2]], units}."""
    if isinstance(value, dict):
        _table(where, value, {"name", "points", "units"}, {"points"})
        pts = _points(where, value["points"])
        if len(pts) != 2:
            raise InputError(f"{where}: a counting line has exactly two points")
        units = _units(where, value.get("units", "px"), pts)
        name = _name(where, value["name"]) if "name" in value else None
    else:
        flat = _numbers(f"{where}: a counting line is [x1, y1, x2, y2] or a table", value, 4)
        pts, units, name = [tuple(flat[:2]), tuple(flat[2:])], "px", None
    if pts[0] == pts[1]:
        raise InputError(f"{where}: counting line has zero length")
    return CountLine((pts[0], pts[1]), units, name)


def parse_cli_line(text: str) -> CountLine:
    """--count-line X1,Y1,X2,Y2 in pixels, or with every value in percent (0%,60%,100%,60%)."""
    where = f"--count-line {text!r}"
    parts = [p.strip() for p in text.split(",")]
    percent = [p.endswith("%") for p in parts]
    if any(percent) and not all(percent):
        raise InputError(f"{where}: give every value in % or none")
    try:
        values = [float(p.rstrip("%")) for p in parts]
    except ValueError:
        raise InputError(f"{where}: expected X1,Y1,X2,Y2 (numbers, or all with %)") from None
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise InputError(f"{where}: expected X1,Y1,X2,Y2 (four finite numbers)")
    if all(percent):
        values = [v / 100.0 for v in values]
        pts = [values[:2], values[2:]]
        return parse_count_line(where, {"points": pts, "units": "fraction"})
    return parse_count_line(where, values)


def _segments_cross(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    def orient(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> float:
        return float((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    return (orient(a, b, c) * orient(a, b, d) < 0) and (orient(c, d, a) * orient(c, d, b) < 0)


def parse_zone(where: str, value: Any) -> Zone:
    """{name, polygon = [[x, y], ...] (3+ vertices, simple, non-zero area), units,
    debounce_s}."""
    if not isinstance(value, dict):
        raise InputError(f"{where}: a zone is a table with name and polygon")
    _table(where, value, {"name", "polygon", "units", "debounce_s"}, {"name", "polygon"})
    name = _name(where, value["name"])
    where = f"{where} {name!r}"
    poly = _polygon(where, value["polygon"])
    units = _units(where, value.get("units", "px"), poly)
    debounce = value.get("debounce_s", ZONE_DEBOUNCE_S)
    if isinstance(debounce, bool) or not isinstance(debounce, (int, float)) or not (
            0 <= debounce < math.inf):
        raise InputError(f"{where}: debounce_s must be a number >= 0")
    return Zone(name, tuple(poly), units, float(debounce))


def parse_roi(where: str, polygon: Any, units: Any = "px") -> Roi:
    """roi = [[x, y], ...] (3+ vertices, simple, non-zero area) with roi_units."""
    poly = _polygon(where, polygon)
    return Roi(tuple(poly), _units(where, units, poly))


def parse_gate(where: str, value: Any) -> Gate:
    """{name, line = [[x1, y1], [x2, y2]] or polygon = [[x, y], ...], units}."""
    if not isinstance(value, dict):
        raise InputError(f"{where}: a gate is a table with name and line or polygon")
    _table(where, value, {"name", "line", "polygon", "units"}, {"name"})
    name = _name(where, value["name"])
    where = f"{where} {name!r}"
    if ("line" in value) == ("polygon" in value):
        raise InputError(f"{where}: give either line = [[x1, y1], [x2, y2]] or polygon")
    if "line" in value:
        pts = _points(f"{where} line", value["line"])
        if len(pts) != 2:
            raise InputError(f"{where}: a gate's line has exactly two points")
        if pts[0] == pts[1]:
            raise InputError(f"{where}: the gate's line has zero length")
        units = _units(where, value.get("units", "px"), pts)
        return Gate(name, line=(pts[0], pts[1]), units=units)
    poly = _polygon(where, value["polygon"])
    return Gate(name, polygon=tuple(poly), units=_units(where, value.get("units", "px"), poly))


def _polygon(where: str, value: Any) -> list[tuple[float, float]]:
    """A polygon's vertices: 3+, simple (no two edges cross), non-zero area."""
    poly = _points(f"{where} polygon", value)
    if len(poly) < 3:
        raise InputError(f"{where}: a polygon needs at least 3 vertices")
    p = np.array(poly)
    n = len(p)
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue            # adjacent through the closing edge
            if _segments_cross(p[i], p[(i + 1) % n], p[j], p[(j + 1) % n]):
                raise InputError(f"{where}: polygon edges cross each other")
    area = 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))
    if not area > 0:
        raise InputError(f"{where}: polygon has zero area")
    return poly


def check_unique_names(source: str, lines: Sequence[CountLine], zones: Sequence[Zone],
                       gates: Sequence[Gate] = ()) -> None:
    """Line, zone and gate names must each be unique (they label rows of the CSVs)."""
    for kind, names in (("count line", [l.name for l in lines if l.name]),
                        ("zone", [z.name for z in zones]), ("gate", [g.name for g in gates])):
        seen: set[str] = set()
        for n in names:
            if n in seen:
                raise InputError(f"{source}: two {kind}s are named {n!r}")
            seen.add(n)


def contains(polygon: np.ndarray, point: np.ndarray) -> bool:
    """Even-odd rule: whether `point` (2,) lies inside `polygon` (n, 2) (ray casting)."""
    x, y = float(point[0]), float(point[1])
    xi, yi = polygon[:, 0], polygon[:, 1]
    xj, yj = np.roll(xi, 1), np.roll(yi, 1)
    straddle = (yi > y) != (yj > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xcross = xi + (y - yi) * (xj - xi) / (yj - yi)
    return bool(np.count_nonzero(straddle & (x < xcross)) % 2)
