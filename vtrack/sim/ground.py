"""Paints the empty road plane as the camera sees it, once per clip.

Every pixel's ray is intersected with the ground (camera.rays); the colour at the hit point
(X, Y) is computed from the road description (vtrack.sim.road): terrain, verges, asphalt with
stains, wheel-path wear and patches, markings. Textures are value noise in world coordinates,
so they shrink with distance like the real road. Beyond `far_m` (and above the horizon) lie a
tree line and the sky. About SAMPLES rays are traced (up to 2 x 2 per pixel) and averaged
down (cv2.INTER_AREA), which anti-aliases thin far-away markings.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from vtrack.sim.camera import Camera
from vtrack.sim.road import Ground, Strip

TILE = 256                 # value-noise lattice size (wraps)
SAMPLES = 800_000          # ray samples for the whole image (anti-aliasing)


class _Noise:
    """Value noise in world coordinates: a random lattice, bilinearly interpolated."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.tile = rng.standard_normal((TILE, TILE)).astype(np.float32)

    def __call__(self, x: np.ndarray, y: np.ndarray, cell: float) -> np.ndarray:
        """Noise (about unit variance) at world points (1-D arrays), lattice spacing `cell` m."""
        return _sample(self.tile, x / cell, y / cell)


def _sample(tile: np.ndarray, mx: np.ndarray, my: np.ndarray) -> np.ndarray:
    """Bilinear samples of a wrapping tile at 1-D coordinates (cv2.remap wants 2-D maps of
    fewer than 32767 rows, so the coordinates are laid out in rows of 1024)."""
    n = mx.size
    if n == 0:
        return np.zeros(0, np.float32)
    rows = -(-n // 1024)
    maps = [np.zeros(rows * 1024, np.float32) for _ in range(2)]
    maps[0][:n], maps[1][:n] = np.mod(mx, TILE), np.mod(my, TILE)
    out = cv2.remap(tile, maps[0].reshape(rows, 1024), maps[1].reshape(rows, 1024),
                    cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
    return out.ravel()[:n]


def supersampling(width: int, height: int) -> float:
    """Samples per pixel along each axis: about SAMPLES in all, between 1 and 2."""
    return float(np.clip(math.sqrt(SAMPLES / (width * height)), 1.0, 2.0))


def paint_ground(camera: Camera, ground: Ground,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The empty scene (H, W, 3) uint8 and the mask of pixels beyond the ground (far scenery
    and sky), which hide whatever is farther than `ground.far_m`."""
    ss = supersampling(camera.width, camera.height)
    h, w = round(camera.height * ss), round(camera.width * ss)
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    rays = camera.rays((u + 0.5) * (camera.width / w) - 0.5,
                       (v + 0.5) * (camera.height / h) - 0.5).reshape(-1, 3).astype(np.float32)
    del u, v
    cx, cy, cz = camera.centre
    dz = rays[:, 2]
    t = np.where(dz < -1e-9, -cz / np.minimum(dz, -1e-9), np.inf)
    x, y = cx + t * rays[:, 0], cy + t * rays[:, 1]
    dist = np.hypot(x - cx, y - cy)
    on_ground = dist <= ground.far_m
    x, y, dist = x[on_ground], y[on_ground], dist[on_ground]
    noise = _Noise(rng)
    img = np.empty((h * w, 3), np.float32)
    local = [strip.local(x, y) for strip in ground.strips]
    near = _terrain(ground, noise, x, y, local)
    _paint_roads(near, ground, noise, x, y, local)
    haze = (1 - np.exp(-dist / (2.5 * ground.far_m)))[:, None].astype(np.float32)
    img[on_ground] = near * (1 - 0.45 * haze) + 0.45 * haze * np.array(ground.sky, np.float32)
    img[~on_ground] = _far_scenery(camera, ground, rng, rays[~on_ground])
    size = (camera.width, camera.height)
    img = cv2.resize(np.clip(img.reshape(h, w, 3), 0, 255), size, interpolation=cv2.INTER_AREA)
    beyond = cv2.resize((~on_ground).reshape(h, w).astype(np.float32), size,
                        interpolation=cv2.INTER_AREA) > 0.5
    return np.round(img).astype(np.uint8), beyond


def _terrain(ground: Ground, noise: _Noise, x: np.ndarray, y: np.ndarray,
             local: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Grass (rural) or grass behind pavements (urban), with the pavement and verges;
    `local` holds the points' (along, across) coordinates on each strip."""
    base = np.array(ground.verge_colour, np.float32)
    tex = (16 * noise(x, y, 6.0) + 9 * noise(x, y, 0.9) + 7 * noise(x + 50, y, 0.1)
           + 5 * noise(x, y + 70, 0.03))
    img = base + tex[..., None] * np.array((0.6, 1.0, 0.85), np.float32)
    edge = np.full(x.shape, np.inf, np.float32)
    for strip, (along, across) in zip(ground.strips, local):
        out = np.maximum(np.maximum(across - strip.left, strip.right - across), 0)
        inside = (along >= strip.start) & (along <= strip.end)
        edge = np.minimum(edge, np.where(inside, out, np.inf))
    if ground.verge == "pavement":
        slab = (np.abs(np.mod(x, 1.8) - 0.9) > 0.86) | (np.abs(np.mod(y, 1.8) - 0.9) > 0.86)
        walk = np.float32(165) + 4 * noise(x, y, 0.3) + 3 * noise(x, y, 0.05) - 30 * slab
        walk = walk[..., None] * np.array((0.98, 1.0, 1.0), np.float32)
        near = (edge < ground.pavement_m)[..., None]
        img = np.where(near, walk, img)
        kerb = ((edge > 0) & (edge < 0.18))[..., None]
        img = np.where(kerb, np.float32(200), img)
    else:
        gravel = np.array((118, 128, 134), np.float32) + (10 * noise(x, y, 0.06))[..., None]
        img = np.where((edge < 0.6)[..., None], gravel, img)
    return img


def _paint_roads(img: np.ndarray, ground: Ground, noise: _Noise, x: np.ndarray,
                 y: np.ndarray, local: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """Asphalt, wear and markings of every strip, in place (markings stop where another
    strip's asphalt begins: a junction box has none). Only points on asphalt are computed."""
    road = [_inside(s, a, c) for s, (a, c) in zip(ground.strips, local)]
    on = np.nonzero(np.logical_or.reduce(road))[0]
    x, y = x[on], y[on]
    local = [(a[on], c[on]) for a, c in local]
    road = [r[on] for r in road]
    tex = 8 * noise(x, y, 2.5) + 4 * noise(x, y, 0.4) + 6 * noise(x + 90, y, 0.04)
    shade = 1 + tex / 100
    for strip, (along, across), inside in zip(ground.strips, local, road):
        for lane in strip.lanes:
            for wheel in (-0.8, 0.8):
                track = np.clip(1 - np.abs(across - lane - wheel) / 0.45, 0, 1)
                shade -= np.where(inside, 0.07 * track, 0)
    for cx, cy, length, width, heading, factor in ground.patches:
        c, s = math.cos(heading), math.sin(heading)
        a, b = (x - cx) * c + (y - cy) * s, -(x - cx) * s + (y - cy) * c
        shade = np.where((np.abs(a) < length / 2) & (np.abs(b) < width / 2), shade * factor, shade)
    out = np.array(ground.asphalt, np.float32) * shade[:, None]
    wear = 0.88 + 0.1 * np.clip(noise(x + 200, y, 0.15), -1.2, 1.2)
    for i, (strip, (along, across)) in enumerate(zip(ground.strips, local)):
        others = np.logical_or.reduce([r for j, r in enumerate(road) if j != i] or [False])
        paint = np.zeros(x.shape, bool)
        colour = np.zeros(x.shape + (3,), np.float32)
        for m in strip.markings:
            hit = np.abs(across - m.offset) <= m.width / 2
            if m.dash:
                hit &= np.mod(along - m.phase, m.period) < m.dash
            colour[hit] = m.colour
            paint |= hit
        for a0, a1, c0, c1 in strip.bars:
            hit = (along >= a0) & (along <= a1) & (across >= c0) & (across <= c1)
            colour[hit] = (222, 226, 226)
            paint |= hit
        for a0, a1, c0, c1 in strip.zebras:
            hit = (along >= a0) & (along <= a1) & (across >= c0) & (across <= c1)
            hit &= np.mod(across - c0, 1.0) < 0.5
            colour[hit] = (215, 218, 218)
            paint |= hit
        paint &= road[i] & ~(others & ~_bars_only(strip, along, across))
        out[paint] = (colour * wear[:, None])[paint]
    img[on] = out


def _inside(strip: Strip, along: np.ndarray, across: np.ndarray) -> np.ndarray:
    """Points on the strip's asphalt."""
    return ((along >= strip.start) & (along <= strip.end) & (across >= strip.right)
            & (across <= strip.left))


def _bars_only(strip: Strip, along: np.ndarray, across: np.ndarray) -> np.ndarray:
    """Stop lines and zebras may lie where strips overlap; lane markings may not."""
    keep = np.zeros(along.shape, bool)
    for a0, a1, c0, c1 in strip.bars + strip.zebras:
        keep |= (along >= a0) & (along <= a1) & (across >= c0) & (across <= c1)
    return keep


def _far_scenery(camera: Camera, ground: Ground, rng: np.random.Generator,
                 rays: np.ndarray) -> np.ndarray:
    """Tree line (with distant fields above it when the camera is high) and sky."""
    horiz = np.hypot(rays[..., 0], rays[..., 1])
    az = np.arctan2(rays[..., 1], rays[..., 0])
    elev = np.arctan2(rays[..., 2], horiz)
    steps = 720
    profile = rng.uniform(7, 16) + 4 * _smooth(rng, steps, 24) + 2.5 * np.abs(_smooth(rng, steps, 2))
    idx = np.mod((az + np.pi) / (2 * np.pi) * steps, steps)
    i0 = np.floor(idx).astype(int) % steps
    frac = (idx - np.floor(idx)).astype(np.float32)
    height = profile[i0] * (1 - frac) + profile[(i0 + 1) % steps] * frac
    top = np.arctan2(height - camera.centre[2], ground.far_m)
    tree = np.array(ground.treeline, np.float32)
    leaf = _smooth2(rng, az, elev)
    trees = tree * (1 + 0.12 * leaf)[..., None]
    sky = np.array(ground.sky, np.float32)
    up = np.clip(elev / 0.5, 0, 1)[..., None]
    skies = sky * (1 - 0.25 * up) + np.array((40, 10, -20), np.float32) * up
    fields = 0.55 * np.array(ground.verge_colour, np.float32) + 0.45 * sky
    out = np.where((rays[..., 2] < 0)[..., None], fields, skies)
    return np.where((elev < top)[..., None], trees, out)


def _smooth(rng: np.random.Generator, n: int, width: int) -> np.ndarray:
    """Periodic smooth noise of n samples with correlation length `width` samples."""
    raw = rng.standard_normal(n)
    kernel = np.exp(-0.5 * (np.arange(-3 * width, 3 * width + 1) / width) ** 2)
    out = np.convolve(np.concatenate([raw[-3 * width:], raw, raw[:3 * width]]), kernel, "valid")
    return out / out.std()


def _smooth2(rng: np.random.Generator, az: np.ndarray, elev: np.ndarray) -> np.ndarray:
    """Leafy texture of the tree line as a function of the viewing direction."""
    tile = cv2.GaussianBlur(rng.standard_normal((TILE, TILE)).astype(np.float32), (0, 0), 1.2)
    tile /= tile.std()
    return _sample(tile, az * 900, elev * 900)
