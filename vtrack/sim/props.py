"""Street furniture as meshes in world coordinates: gantry signs, lamp posts, guard rails,
median barriers, signal heads, tree trunks and buildings. Long objects are cut into short
blocks, because the painter's order and the depth test work per block."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vtrack.sim.shapes import Mesh, MeshBuilder

STEEL = (150, 152, 150)
CONCRETE = (176, 180, 182)
BARK = (45, 60, 75)
LAMP_COLOURS = ((60, 200, 40), (30, 170, 240), (40, 40, 230))   # green, amber, red (lit)


@dataclass(frozen=True)
class Lamp:
    """One lamp of a signal head: a disc (8 world points) facing `normal`, lit while its
    signal group shows `aspect` (0 green, 1 amber, 2 red)."""

    polygon: np.ndarray
    normal: np.ndarray
    group: int
    aspect: int


def _frame(b: MeshBuilder, origin: tuple[float, float], heading: float) -> None:
    """Rotate and shift everything added to b so far from local to world coordinates."""
    c, s = math.cos(heading), math.sin(heading)
    pts = np.array(b.points)
    x = origin[0] + c * pts[:, 0] - s * pts[:, 1]
    y = origin[1] + s * pts[:, 0] + c * pts[:, 1]
    b.points = [tuple(p) for p in np.column_stack([x, y, pts[:, 2]])]
    n = np.array(b.face_normal)
    b.face_normal = list(np.column_stack([c * n[:, 0] - s * n[:, 1], s * n[:, 0] + c * n[:, 1],
                                          n[:, 2]]))


def gantry(rng: np.random.Generator, x: float, right: float, left: float,
           signs: list[tuple[float, float]]) -> Mesh:
    """A sign gantry across the road at x: two posts, a beam at ~7 m and sign boards
    (centre across, width) facing both ways, with white lettering."""
    b = MeshBuilder()
    top = rng.uniform(6.8, 7.6)
    for y in (right - 0.8, left + 0.8):
        b.block((x - 0.2, x + 0.2), 0.2, (0, top + 0.4), STEEL, y=y)
    step = 4.0
    edges = np.arange(right - 1.0, left + 1.0, step).tolist() + [left + 1.0]
    for y0, y1 in zip(edges, edges[1:]):
        b.block((x - 0.25, x + 0.25), (y1 - y0) / 2, (top, top + 0.4), STEEL, y=(y0 + y1) / 2)
    colour = [(150, 75, 20), (55, 115, 30)][rng.integers(2)]
    for centre, width in signs:
        low = top - rng.uniform(1.6, 2.4)
        board = b.block((x - 0.08, x + 0.08), width / 2, (low, top + 0.2), colour, y=centre)
        for face in ("back", "front"):
            b.decal(board[face], (0.03, 0.97), (0.04, 0.96), (230, 230, 230))
            b.decal(board[face], (0.06, 0.94), (0.08, 0.92), colour)
            for row in range(int(rng.integers(2, 4))):
                v = 0.18 + row * 0.25
                u0 = rng.uniform(0.1, 0.3)
                b.decal(board[face], (u0, u0 + rng.uniform(0.3, 0.6)), (v, v + 0.1),
                        (235, 235, 235))
    return b.build()


def lamp_post(x: float, y: float, arm: float) -> Mesh:
    """A lighting column at (x, y) with an arm reaching `arm` m across (signed)."""
    b = MeshBuilder()
    height = 9.0
    b.block((x - 0.1, x + 0.1), 0.1, (0, height), STEEL, y=y)
    b.block((x - 0.06, x + 0.06), abs(arm) / 2, (height - 0.12, height), STEEL, y=y + arm / 2)
    b.block((x - 0.25, x + 0.25), 0.18, (height - 0.3, height - 0.05), (90, 90, 92),
            y=y + arm)
    return b.build()


def guard_rail(x0: float, x1: float, y: float, segment: float = 4.0) -> Mesh:
    """A steel guard rail along x at y: posts every 2 m and a beam in short segments."""
    b = MeshBuilder()
    xs = np.arange(x0, x1, segment)
    for a in xs:
        b.block((a, min(a + segment, x1)), 0.05, (0.5, 0.82), STEEL, y=y)
        for p in (a, a + segment / 2):
            b.block((p - 0.06, p + 0.06), 0.06, (0, 0.72), (110, 112, 112), y=y + 0.12)
    return b.build()


def median_barrier(x0: float, x1: float, y: float, segment: float = 6.0) -> Mesh:
    """A concrete barrier (New Jersey profile: wide foot, narrow top) along x at y."""
    b = MeshBuilder()
    for a in np.arange(x0, x1, segment):
        b.block((a, min(a + segment, x1)), 0.3, (0, 0.82), CONCRETE, top_half_width=0.12, y=y)
    return b.build()


def trunk(x: float, y: float, height: float, radius: float = 0.18) -> Mesh:
    """A tree trunk up to `height` (its crown is a render.Crown)."""
    b = MeshBuilder()
    b.block((x - radius, x + radius), radius, (0, height), BARK, top_x=(x - 0.7 * radius,
                                                                      x + 0.7 * radius),
            top_half_width=0.7 * radius, y=y)
    return b.build()


def signal_head(origin: tuple[float, float], facing: float, group: int,
                height: float = 3.4) -> tuple[Mesh, list[Lamp]]:
    """A signal pole at `origin` with a head facing the heading `facing` (the direction the
    lamps look, towards the approaching traffic): red, amber and green lamps."""
    b = MeshBuilder()
    b.block((-0.08, 0.08), 0.08, (0, height), (60, 62, 60))
    head = b.block((-0.2, 0.12), 0.18, (height - 1.0, height), (35, 35, 38))
    lamps_local = []
    for aspect, v in ((2, (0.68, 0.94)), (1, (0.38, 0.64)), (0, (0.08, 0.34))):
        b.decal(head["front"], (0.2, 0.8), v, (45, 45, 50), round_=True)
        lamps_local.append((aspect, len(b.points) - 8))
    _frame(b, origin, facing)
    mesh = b.build()
    normal = mesh.face_normal[head["front"]]
    lamps = [Lamp(mesh.points[i:i + 8] + 0.01 * normal, normal, group, aspect)
             for aspect, i in lamps_local]
    return mesh, lamps


def building(rng: np.random.Generator, corner: tuple[float, float], heading: float,
             width: float, depth: float, side: int) -> Mesh:
    """A block of flats: `width` m along `heading` from `corner`, `depth` m to its left
    (side +1) or right (side -1), with rows of windows on every wall."""
    b = MeshBuilder()
    height = rng.uniform(7, 22)
    wall = tuple(float(c) for c in rng.choice([(170, 185, 200), (120, 130, 150), (150, 150, 150),
                                                (90, 110, 160), (200, 205, 205)]) * rng.uniform(0.8, 1.05))
    faces = b.block((0, width), depth / 2, (0, height), wall, y=side * depth / 2)
    floors = int(height // 3)
    for name in ("right", "left", "front", "back"):
        span = width if name in ("right", "left") else depth
        cols = max(1, int(span // 3.2))
        for f in range(floors):
            for c in range(cols):
                b.decal(faces[name], ((c + 0.25) / cols, (c + 0.75) / cols),
                        ((f + 0.35) / floors, (f + 0.8) / floors), (70, 62, 55))
    _frame(b, corner, heading)
    return b.build()
