"""Drawing meshes, shadows and tree crowns into a frame's buffers.

A frame is three buffers: the colour image, an id buffer (which vehicle owns each pixel, 0 for
none) and a depth buffer (distance from the camera of the block that owns the pixel). Meshes
are drawn with the painter's algorithm: callers sort objects far to near, a mesh's blocks are
sorted far to near, and a block shows only its faces turned towards the camera (a convex
block's front faces never overlap). The id and depth buffers receive each block's silhouette,
the convex hull of its projected corners. Polygons are filled with cv2.fillConvexPoly in
fixed point (SHIFT fractional bits), so motion is smooth to 1/16 pixel.

Shadows: a point P casts its shadow along the sun direction L (unit, towards the sun) onto the
road plane at P - (P_z / L_z) L; a block's shadow is the convex hull of its corners' shadows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from vtrack.sim.camera import NEAR_M, Camera, clip_near
from vtrack.sim.shapes import Mesh

SHIFT = 4
ONE = 1 << SHIFT
SILHOUETTE_MAX_PX = 2_000_000      # larger silhouettes are measured at reduced resolution
DETAIL_PX = 5                      # faces smaller than this many pixels get no decals


@dataclass(frozen=True)
class Light:
    """The sun (unit vector towards it), ambient and direct shares, and the brightness factor
    of the ground in shadow."""

    sun: np.ndarray
    ambient: float
    direct: float
    shadow: float

    def shade(self, normals: np.ndarray) -> np.ndarray:
        """Brightness factor of surfaces with these unit normals (Lambert plus sky light)."""
        return (self.ambient + self.direct * np.maximum(normals @ self.sun, 0.0)
                + 0.12 * normals[:, 2])

    def cast(self, points: np.ndarray) -> np.ndarray:
        """Road-plane shadow points (N, 3) of world points (N, 3) (module docstring)."""
        t = points[:, 2:3] / self.sun[2]
        return np.column_stack([points[:, :2] - t * self.sun[:2], np.zeros(len(points))])


@dataclass
class Buffers:
    """The buffers of one frame being drawn (module docstring)."""

    image: np.ndarray      # (H, W, 3) uint8
    ids: np.ndarray        # (H, W) int32
    depth: np.ndarray      # (H, W) float32, inf where no vehicle

    @classmethod
    def start(cls, background: np.ndarray) -> Buffers:
        """Buffers holding a copy of the background and no vehicles."""
        h, w = background.shape[:2]
        return cls(background.copy(), np.zeros((h, w), np.int32),
                   np.full((h, w), np.inf, np.float32))


def fixed(pixels: np.ndarray) -> np.ndarray:
    """Pixel coordinates as the int32 fixed-point polygon fillConvexPoly takes."""
    return np.round(pixels * ONE).astype(np.int32)


@dataclass(frozen=True)
class Placed:
    """A mesh placed in the world (shapes.place) to be drawn with id `ident` (0: scenery)."""

    mesh: Mesh
    world: np.ndarray
    normals: np.ndarray
    ident: int


def _stack(objects: list[Placed], field: str, offsets: list[int]) -> np.ndarray:
    """A mesh index array of every object, shifted to index the concatenated points."""
    return np.concatenate([getattr(o.mesh, field) + off for o, off in zip(objects, offsets)])


def _offsets(objects: list[Placed], field: str) -> list[int]:
    """Where each object's entries of a mesh array start once all are concatenated."""
    counts = [len(getattr(o.mesh, field)) for o in objects]
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int).tolist()


def draw_all(buf: Buffers, camera: Camera, light: Light,
             objects: list[Placed]) -> list[list[np.ndarray]]:
    """Paint placed meshes in the given order (callers sort them far to near), each one's
    blocks far to near; write each block's silhouette with the object's ident and the block's
    distance into the id and depth buffers. Returns each object's block silhouettes (fixed
    point convex polygons) for the ground truth. Projections, visibility and shading are
    computed for all objects at once; only the fills loop."""
    if not objects:
        return []
    p_off, f_off = _offsets(objects, "points"), _offsets(objects, "faces")
    d_off, b_off = _offsets(objects, "decals"), _offsets(objects, "blocks")
    world = np.concatenate([o.world for o in objects])
    cam = camera.to_camera(world)
    front = cam[:, 2] >= NEAR_M
    px = np.zeros((len(cam), 2))
    px[front] = camera.pixels(cam[front])
    pts = fixed(px)
    faces = _stack(objects, "faces", p_off)
    normals = np.concatenate([o.normals for o in objects])
    visible = np.einsum("ij,ij->i", normals, camera.centre - world[faces].mean(1)) > 0
    whole_face = front[faces].all(1)
    detail = np.ptp(pts[faces], axis=1).max(1) >= DETAIL_PX * ONE
    lum = light.shade(normals)
    colour = np.clip(np.concatenate([o.mesh.face_colour for o in objects]) * lum[:, None],
                     0, 255).tolist()
    decals = _stack(objects, "decals", p_off)
    dec_face = _stack(objects, "decal_face", f_off)
    glow = np.concatenate([o.mesh.decal_glow for o in objects])
    dec_colour = np.clip(np.concatenate([o.mesh.decal_colour for o in objects])
                         * np.where(glow, 1.0, lum[dec_face])[:, None], 0, 255).tolist()
    blocks = _stack(objects, "blocks", p_off)
    dist = camera.distance(world[blocks].mean(1))
    whole_block = front[blocks].all(1)
    visible, whole_face, detail = visible.tolist(), whole_face.tolist(), detail.tolist()
    out = []
    for o, po, fo, do, bo in zip(objects, p_off, f_off, d_off, b_off):
        mesh = o.mesh
        nb = len(mesh.blocks)
        if not front[po:po + len(o.world)].any():
            out.append([])
            continue
        hulls = []
        for b in (bo + np.argsort(-dist[bo:bo + nb], kind="stable")).tolist():
            outline = [px[blocks[b]]] if whole_block[b] else []
            for lf in mesh.block_faces[b - bo].tolist():
                f = fo + lf
                if whole_face[f]:
                    poly = pts[faces[f]]
                    if not whole_block[b]:
                        outline.append(px[faces[f]])
                else:
                    part = clip_near(cam[faces[f]])
                    if len(part) < 3:
                        continue
                    outline.append(camera.pixels(part))
                    poly = fixed(outline[-1])
                if not visible[f]:
                    continue
                cv2.fillConvexPoly(buf.image, poly, colour[f], cv2.LINE_AA, SHIFT)
                if whole_face[f] and detail[f]:
                    for d in mesh.face_decals[lf].tolist():
                        cv2.fillConvexPoly(buf.image, pts[decals[do + d]], dec_colour[do + d],
                                           cv2.LINE_AA, SHIFT)
            if not outline:
                continue
            hull = cv2.convexHull(fixed(np.concatenate(outline)))
            cv2.fillConvexPoly(buf.ids, hull, o.ident, cv2.LINE_8, SHIFT)
            cv2.fillConvexPoly(buf.depth, hull, float(dist[b]), cv2.LINE_8, SHIFT)
            hulls.append(hull)
        out.append(hulls)
    return out


def silhouette(hulls: list[np.ndarray]) -> tuple[float, tuple[int, int, int, int]]:
    """Pixel area and bounding box (x0, y0, x1, y1), x1/y1 exclusive, of the union of fixed
    point polygons, rasterised exactly as draw_all fills the id buffer (at reduced
    resolution, and the box from the vertices, when it is huge)."""
    allpts = np.concatenate([h.reshape(-1, 2) for h in hulls]).astype(np.int64)
    x0, y0 = (allpts.min(0) >> SHIFT) - 1
    x1, y1 = (allpts.max(0) >> SHIFT) + 2
    w, h = int(x1 - x0), int(y1 - y0)
    scale = min(1.0, math.sqrt(SILHOUETTE_MAX_PX / max(w * h, 1)))
    if scale < 1.0:
        canvas = np.zeros((max(1, int(h * scale) + 2), max(1, int(w * scale) + 2)), np.uint8)
        for hull in hulls:
            local = np.round((hull.reshape(-1, 2) - np.array([x0, y0]) * ONE) * scale)
            cv2.fillConvexPoly(canvas, local.astype(np.int32), 1, cv2.LINE_8, SHIFT)
        lo = (allpts.min(0) + ONE // 2) >> SHIFT
        hi = (allpts.max(0) + ONE // 2) >> SHIFT
        return cv2.countNonZero(canvas) / scale ** 2, (int(lo[0]), int(lo[1]),
                                                       int(hi[0]) + 1, int(hi[1]) + 1)
    canvas = np.zeros((h, w), np.uint8)
    offset = np.array([x0, y0], np.int32) * ONE
    for hull in hulls:
        cv2.fillConvexPoly(canvas, hull.reshape(-1, 2) - offset, 1, cv2.LINE_8, SHIFT)
    bx, by, bw, bh = cv2.boundingRect(canvas)
    return float(cv2.countNonZero(canvas)), (int(x0 + bx), int(y0 + by), int(x0 + bx + bw),
                                             int(y0 + by + bh))


def shadow_polygons(camera: Camera, light: Light, objects: list[Placed]) -> list[np.ndarray]:
    """Image polygons (fixed point) of the shadows the objects' blocks cast on the road."""
    if not objects:
        return []
    corners = np.concatenate([o.world[o.mesh.blocks] for o in objects])      # (B, 8, 3)
    ground = light.cast(corners.reshape(-1, 3))
    cam = camera.to_camera(ground).reshape(-1, 8, 3)
    ok = cam[:, :, 2].min(1) >= NEAR_M
    px = fixed(camera.pixels(cam[ok]))
    return [cv2.convexHull(p) for p in px]


def darken(image: np.ndarray, mask: np.ndarray, factor: float) -> None:
    """Multiply the pixels under a uint8 mask (non-zero) by `factor`, in place (only the
    mask's bounding box is touched)."""
    x, y, w, h = cv2.boundingRect(mask)
    if w and h:
        part = image[y:y + h, x:x + w]
        cv2.copyTo(cv2.convertScaleAbs(part, alpha=factor), mask[y:y + h, x:x + w], part)


@dataclass(frozen=True)
class Crown:
    """The leafy crown of a tree or bush: a ball of `radius` m at `centre`, drawn as a
    billboard sprite over the vehicles behind it; `sway` m is how far its top moves."""

    centre: tuple[float, float, float]
    radius: float
    colour: tuple[float, float, float]
    sway: float


class CrownSprite:
    """A crown's leafy image and its motion: the whole crown swings (sway * sin(w t + phi))
    and its leaves flutter (a smooth random displacement field that changes with time)."""

    def __init__(self, crown: Crown, camera: Camera, light: Light,
                 rng: np.random.Generator) -> None:
        self.crown = crown
        self.rim: np.ndarray | None = None        # the crown's shadow outline on the road
        cam = camera.to_camera(np.array(crown.centre))
        self.depth = float(np.linalg.norm(np.array(crown.centre) - camera.centre))
        self.visible = cam[2] > crown.radius + NEAR_M
        if not self.visible:
            return
        centre = camera.pixels(cam)
        r = float(camera.focal * crown.radius / cam[2])
        self.px_per_m = float(camera.focal / cam[2])
        half = int(math.ceil(1.35 * r + 3 * crown.sway * self.px_per_m + 2))
        size = 2 * half + 1
        left, top = int(round(centre[0])) - half, int(round(centre[1])) - half
        # the part of the sprite inside the canvas: (x0, y0) canvas, (sx, sy) sprite corner
        self.x0, self.y0 = max(left, 0), max(top, 0)
        x1, y1 = min(left + size, camera.width), min(top + size, camera.height)
        self.visible = x1 > self.x0 and y1 > self.y0
        if not self.visible:
            return
        yy, xx = np.mgrid[0:size, 0:size].astype(np.float32)
        d = np.hypot(xx - half, yy - half) / max(r, 1.0)
        clumps = _blur_noise(rng, size, max(r / 3.5, 0.8))
        leaves = _blur_noise(rng, size, max(r / 14, 0.5))
        alpha = np.clip((1 - d ** 2) * 2.2 + 0.9 * clumps + 0.25 * leaves, 0, 1)
        self.alpha = np.clip((alpha - 0.35) * 3, 0, 1).astype(np.float32)
        lit = np.clip(0.8 - 0.35 * ((xx - half) * 0.5 + (yy - half)) / max(r, 1.0), 0.45, 1.3)
        tone = lit * (1 + 0.18 * clumps + 0.16 * leaves) * (light.ambient + light.direct * 0.6)
        self.rgb = np.clip(np.array(crown.colour) * tone[..., None], 0, 255).astype(np.uint8)
        win = (slice(self.y0 - top, y1 - top), slice(self.x0 - left, x1 - left))
        self.xx, self.yy = xx[win], yy[win]
        self.weight = np.clip(1.2 - self.yy / size, 0.2, 1.0)
        flutter = (_blur_noise(rng, size, max(r / 6, 0.7)), _blur_noise(rng, size, max(r / 6, 0.7)))
        self.flutter = (flutter[0][win], flutter[1][win])
        self.still = (self.rgb[win], self.alpha[win])
        self.phase, self.freq = rng.uniform(0, 2 * np.pi), rng.uniform(0.25, 0.6)

    def offset_m(self, t: float) -> float:
        """Horizontal swing (m) of the crown top at time t."""
        w = 2 * np.pi * self.freq * t + self.phase
        return self.crown.sway * (math.sin(w) + 0.35 * math.sin(2.7 * w + 1.0))

    def draw(self, buf: Buffers, t: float, moving: bool) -> None:
        """Blend the crown over the frame where it is nearer than the vehicles there."""
        if not self.visible:
            return
        rgb, alpha = self.still
        if moving:
            swing = self.offset_m(t) * self.px_per_m
            c, s = math.cos(3.1 * t + self.phase), math.sin(2.3 * t)
            amp = max(0.6, 0.25 * self.crown.sway * self.px_per_m)
            fx = amp * (c * self.flutter[0] + s * self.flutter[1])
            fy = amp * (s * self.flutter[0] - c * self.flutter[1])
            mx = self.xx - swing * self.weight - fx
            my = self.yy - fy
            rgb = cv2.remap(self.rgb, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            alpha = cv2.remap(self.alpha, mx, my, cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT)
        h, w = alpha.shape
        region = buf.image[self.y0:self.y0 + h, self.x0:self.x0 + w]
        alpha = alpha * (buf.depth[self.y0:self.y0 + h, self.x0:self.x0 + w] > self.depth)
        region[:] = cv2.blendLinear(rgb, region, alpha, 1 - alpha)
        buf.ids[self.y0:self.y0 + h, self.x0:self.x0 + w][alpha >= 0.5] = 0

    def shadow(self, camera: Camera, light: Light, t: float, moving: bool) -> np.ndarray | None:
        """Image polygon (fixed point) of the crown's shadow on the road."""
        if self.rim is None:
            ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
            a = np.cross(light.sun, [0.0, 0.0, 1.0])
            a = a / max(np.linalg.norm(a), 1e-9)
            b = np.cross(light.sun, a)
            self.rim = light.cast(np.array(self.crown.centre) + self.crown.radius * 0.85
                                  * (np.outer(np.cos(ang), a) + np.outer(np.sin(ang), b)))
        rim = self.rim
        if moving and self.visible:
            rim = rim + np.array([self.offset_m(t), 0.0, 0.0])
        cam = camera.to_camera(rim)
        if cam[:, 2].min() < NEAR_M:
            return None
        return cv2.convexHull(fixed(camera.pixels(cam)))


def _blur_noise(rng: np.random.Generator, size: int, sigma: float) -> np.ndarray:
    """A square of smooth noise with unit standard deviation."""
    raw = rng.standard_normal((size, size)).astype(np.float32)
    out = cv2.GaussianBlur(raw, (0, 0), sigma)
    return out / max(float(out.std()), 1e-6)
