"""3-D shapes of vehicles and street furniture: convex blocks with painted faces.

A mesh is a set of blocks (convex hexahedra: a bottom and a top rectangle, the top possibly
narrower or shorter, as for a car's cabin) in the frame of one of its rigid units (x forward,
y left, z up, metres). Each visible face is painted in its colour, shaded by the sun; decals
(windows, lights, wheels, signs) are convex polygons lying on a face, painted after it.
Since every block is convex, a block's silhouette is the convex hull of its eight corners.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

# Corner order: bottom rear-right, front-right, front-left, rear-left, then the same on top.
# Each face lists (u=0,v=0), (u=1,v=0), (u=1,v=1), (u=0,v=1) so decals address it by (u, v):
# sides run rear -> front and bottom -> top; front/back right -> left; the top rear -> front.
FACES = {"right": (0, 1, 5, 4), "left": (3, 2, 6, 7), "front": (1, 2, 6, 5),
         "back": (0, 3, 7, 4), "top": (4, 5, 6, 7)}
POLY = 8                   # every decal is stored as an 8-vertex convex polygon


@dataclass(frozen=True)
class Mesh:
    """Blocks, faces and decals of one object as arrays (module docstring)."""

    points: np.ndarray         # (P, 3) in the frame of the point's unit
    point_unit: np.ndarray     # (P,)
    blocks: np.ndarray         # (B, 8) corner indices
    faces: np.ndarray          # (F, 4) corner indices
    face_block: np.ndarray     # (F,)
    face_colour: np.ndarray    # (F, 3) BGR before shading
    face_normal: np.ndarray    # (F, 3) outward unit normal in the unit frame
    decals: np.ndarray         # (D, 8) vertex indices into points
    decal_face: np.ndarray     # (D,)
    decal_colour: np.ndarray   # (D, 3)
    decal_glow: np.ndarray     # (D,) bool: lamps, not shaded by the sun

    @property
    def units(self) -> int:
        """Number of rigid units (a tractor and its trailer are two)."""
        return int(self.point_unit.max()) + 1

    @cached_property
    def block_faces(self) -> tuple[np.ndarray, ...]:
        """Face indices of each block."""
        return tuple(np.nonzero(self.face_block == b)[0] for b in range(len(self.blocks)))

    @cached_property
    def face_decals(self) -> tuple[np.ndarray, ...]:
        """Decal indices of each face, in the order they were added."""
        return tuple(np.nonzero(self.decal_face == f)[0] for f in range(len(self.faces)))


@dataclass
class MeshBuilder:
    """Collects blocks and decals; `build()` freezes them into a Mesh."""

    points: list = field(default_factory=list)
    point_unit: list = field(default_factory=list)
    blocks: list = field(default_factory=list)
    faces: list = field(default_factory=list)
    face_block: list = field(default_factory=list)
    face_colour: list = field(default_factory=list)
    face_normal: list = field(default_factory=list)
    decals: list = field(default_factory=list)
    decal_face: list = field(default_factory=list)
    decal_colour: list = field(default_factory=list)
    decal_glow: list = field(default_factory=list)

    def block(self, x: tuple[float, float], half_width: float, z: tuple[float, float],
              colour: tuple[float, float, float], *, unit: int = 0,
              top_x: tuple[float, float] | None = None, top_half_width: float | None = None,
              y: float = 0.0) -> dict[str, int]:
        """Add a block: bottom rectangle x[0]..x[1] by +-half_width (centred on y) at z[0], top
        rectangle top_x by +-top_half_width at z[1]; returns its face indices by name."""
        tx = top_x or x
        tw = half_width if top_half_width is None else top_half_width
        corners = [(x[0], y - half_width, z[0]), (x[1], y - half_width, z[0]),
                   (x[1], y + half_width, z[0]), (x[0], y + half_width, z[0]),
                   (tx[0], y - tw, z[1]), (tx[1], y - tw, z[1]),
                   (tx[1], y + tw, z[1]), (tx[0], y + tw, z[1])]
        base = len(self.points)
        self.points.extend(corners)
        self.point_unit.extend([unit] * 8)
        b = len(self.blocks)
        self.blocks.append(list(range(base, base + 8)))
        pts = np.array(corners)
        centre = pts.mean(0)
        names = {}
        for name, idx in FACES.items():
            quad = pts[list(idx)]
            n = np.cross(quad[1] - quad[0], quad[3] - quad[0])
            if np.linalg.norm(n) < 1e-12:       # degenerate face (a tapered edge)
                n = quad.mean(0) - centre
            n = n / np.linalg.norm(n)
            if np.dot(n, quad.mean(0) - centre) < 0:
                n = -n
            names[name] = len(self.faces)
            self.faces.append([base + i for i in idx])
            self.face_block.append(b)
            self.face_colour.append(colour)
            self.face_normal.append(n)
        return names

    def decal(self, face: int, u: tuple[float, float], v: tuple[float, float],
              colour: tuple[float, float, float], *, round_: bool = False,
              glow: bool = False) -> None:
        """Paint the rectangle u[0]..u[1] x v[0]..v[1] (an ellipse inside it if round_) of
        face coordinates on `face` (FACES)."""
        if round_:
            ang = np.linspace(0, 2 * np.pi, POLY, endpoint=False)
            uu = u[0] + (u[1] - u[0]) * 0.5 * (1 + np.cos(ang))
            vv = v[0] + (v[1] - v[0]) * 0.5 * (1 + np.sin(ang))
        else:
            uu = np.array([u[0], u[1], u[1], u[0]] * 2)
            vv = np.array([v[0], v[0], v[1], v[1]] * 2)
        quad = np.array([self.points[i] for i in self.faces[face]])
        verts = (np.outer((1 - uu) * (1 - vv), quad[0]) + np.outer(uu * (1 - vv), quad[1])
                 + np.outer(uu * vv, quad[2]) + np.outer((1 - uu) * vv, quad[3]))
        unit = self.point_unit[self.faces[face][0]]
        base = len(self.points)
        self.points.extend(map(tuple, verts))
        self.point_unit.extend([unit] * POLY)
        self.decals.append(list(range(base, base + POLY)))
        self.decal_face.append(face)
        self.decal_colour.append(colour)
        self.decal_glow.append(glow)

    def build(self) -> Mesh:
        """The arrays of everything added so far."""
        dec = np.array(self.decals, dtype=np.int64).reshape(-1, POLY)
        return Mesh(np.array(self.points, float), np.array(self.point_unit, np.int64),
                    np.array(self.blocks, np.int64), np.array(self.faces, np.int64),
                    np.array(self.face_block, np.int64),
                    np.array(self.face_colour, float).reshape(-1, 3),
                    np.array(self.face_normal, float).reshape(-1, 3), dec,
                    np.array(self.decal_face, np.int64),
                    np.array(self.decal_colour, float).reshape(-1, 3),
                    np.array(self.decal_glow, bool))


def place(mesh: Mesh, origin: np.ndarray, heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World points (P, 3) and face normals (F, 3) of a mesh whose unit u has its frame origin
    at origin[u] (x, y on the road) and its x axis at heading[u] (radians)."""
    c, s = np.cos(heading), np.sin(heading)
    u = mesh.point_unit
    p = mesh.points
    world = np.column_stack([origin[u, 0] + c[u] * p[:, 0] - s[u] * p[:, 1],
                             origin[u, 1] + s[u] * p[:, 0] + c[u] * p[:, 1], p[:, 2]])
    fu = u[mesh.faces[:, 0]]
    n = mesh.face_normal
    normals = np.column_stack([c[fu] * n[:, 0] - s[fu] * n[:, 1],
                               s[fu] * n[:, 0] + c[fu] * n[:, 1], n[:, 2]])
    return world, normals
