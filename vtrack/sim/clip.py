"""Renders a perspective scene preset into OUT_DIR: video.avi, gt.csv, world.csv and
calibration.toml (`vtrack synth --scene mast|side|junction`).

Each frame: the pre-painted background (road plane, far scenery, street furniture), the signal
lamps of the moment, the shadows of vehicles and tree crowns on the road, the vehicles far to
near, then the street furniture again wherever it is nearer than the vehicle under it, then
the tree crowns. The frame is drawn on a canvas a few pixels larger than the image and cut out
at the camera shake's offset; then exposure and sensor noise are applied and MJPG encodes it.
The ground truth comes from the same id buffer (vtrack.sim.groundtruth).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np

from vtrack.errors import InputError
from vtrack.fileio import write_text
from vtrack.sim import props
from vtrack.sim.camera import NEAR_M, Camera
from vtrack.sim.dynamics import Drivers, Motion, simulate
from vtrack.sim.ground import paint_ground
from vtrack.sim.groundtruth import (IdBook, Row, Seen, calibration_toml, choose_landmarks,
                                    format_world, frame_rows)
from vtrack.sim.nuisance import Exposure, NoiseBank, shake_offsets
from vtrack.sim.avi import write_mjpeg_avi
from vtrack.sim.output import check_settings, format_gt
from vtrack.sim.paths import PathSet
from vtrack.sim.population import draw_flow, populate
from vtrack.sim.render import (SHIFT, Buffers, CrownSprite, Light, Placed, darken, draw_all,
                               fixed, shadow_polygons, silhouette)
from vtrack.sim.scenes import Layout, build_layout
from vtrack.sim.shapes import place
from vtrack.sim.vehicles import Vehicle


@dataclass(frozen=True)
class Scene:
    """A preset drawn from the seed: layout, light, traffic and its simulated motion."""

    name: str
    layout: Layout
    light: Light
    paths: PathSet
    drivers: Drivers
    fleet: tuple[Vehicle, ...]
    motion: Motion
    fps: float
    nuisances: frozenset[str]

    @property
    def frames(self) -> int:
        """Number of video frames."""
        return self.motion.s.shape[1]

    @cached_property
    def _units(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All vehicles' units flattened: first unit index of each vehicle (K + 1,), and each
        unit's (front, rear) offsets (U, 2) and vehicle (U,)."""
        counts = [len(v.units) for v in self.fleet]
        first = np.concatenate([[0], np.cumsum(counts)]).astype(int)
        offsets = np.concatenate([v.units for v in self.fleet]).reshape(-1, 2)
        return first, offsets, np.repeat(np.arange(len(self.fleet)), counts)

    def centres(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The vehicles on the road in frame n and their footprint centres (K, 2), halfway
        between their fronts and rears."""
        active = np.nonzero(~np.isnan(self.motion.s[:, n]))[0]
        s = self.motion.s[active, n]
        length = np.array([self.fleet[k].length for k in active])
        pts, _ = self.paths.pose(np.tile(self.drivers.path[active], 2),
                                 np.concatenate([s, s - length]))
        return active, 0.5 * (pts[:len(active)] + pts[len(active):])

    def units(self, vehicles: np.ndarray, n: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """Road-plane origin (U, 2) and heading (U,) of each given vehicle's units in frame
        n: a unit spans the arc lengths [s - rear, s - front] and points from its rear to
        its front."""
        first, offsets, owner = self._units
        idx = np.concatenate([np.arange(first[k], first[k + 1]) for k in vehicles] or [[]])
        idx = idx.astype(int)
        s = self.motion.s[owner[idx], n]
        path = self.drivers.path[owner[idx]]
        pts, _ = self.paths.pose(np.tile(path, 2), np.concatenate([s - offsets[idx, 0],
                                                                   s - offsets[idx, 1]]))
        front, rear = pts[:len(idx)], pts[len(idx):]
        d = front - rear
        heading = np.arctan2(d[:, 1], d[:, 0])
        cuts = np.cumsum([first[k + 1] - first[k] for k in vehicles])[:-1]
        return list(zip(np.split(rear, cuts), np.split(heading, cuts)))


def draw_light(rng: np.random.Generator) -> Light:
    """The sun from any azimuth 20-65 degrees up; one clip in five is overcast."""
    az, el = rng.uniform(0, 2 * np.pi), math.radians(rng.uniform(20, 65))
    sun = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    if rng.random() < 0.2:
        return Light(sun, 0.85, 0.2, rng.uniform(0.82, 0.9))
    return Light(sun, rng.uniform(0.5, 0.65), rng.uniform(0.4, 0.6), rng.uniform(0.42, 0.65))


def build_scene(name: str, frames: int, vehicles: int | None, width: int, height: int,
                fps: float, seed: int, nuisances: frozenset[str]) -> Scene:
    """Draw preset `name` from the seed and simulate its traffic."""
    rng_layout, rng_traffic, rng_light = (np.random.default_rng(s) for s in
                                          np.random.SeedSequence(seed).spawn(3))
    layout = build_layout(name, rng_layout, width, height, "parked" in nuisances)
    paths = PathSet(layout.paths)
    duration = frames / fps
    if vehicles is None:
        flow = draw_flow(rng_traffic, layout)
        count = round(flow * duration)
    else:
        count, flow = vehicles, vehicles / (0.9 * duration)
    drivers, fleet, t_start = populate(rng_traffic, layout, duration, count, flow,
                                       "inview" in nuisances, "parked" in nuisances,
                                       "mix" in nuisances)
    motion = simulate(paths, drivers, layout.signals, frames, fps, t_start)
    return Scene(name, layout, draw_light(rng_light), paths, drivers, fleet, motion, fps,
                 nuisances)


class ClipRenderer:
    """Frames and ground truth of a scene, in order (module docstring)."""

    def __init__(self, scene: Scene, seed: int) -> None:
        self.scene = scene
        on = scene.nuisances
        rng_tex, rng_shake, rng_exp, rng_noise, rng_crown = (
            np.random.default_rng(s) for s in np.random.SeedSequence([seed, 1]).spawn(5))
        size = scene.layout.camera.width, scene.layout.camera.height
        self.shake = (shake_offsets(rng_shake, scene.frames, scene.fps, size[0] / 640)
                      if "shake" in on else np.zeros((scene.frames, 2)))
        self.margin = int(math.ceil(np.abs(self.shake).max())) + 1 if "shake" in on else 0
        self.camera = scene.layout.camera.padded(self.margin)
        self.sway, self.shadows = "vegetation" in on, "shadows" in on
        self.crowns = sorted((CrownSprite(c, self.camera, scene.light, rng_crown)
                              for c in scene.layout.crowns), key=lambda c: -c.depth)
        self.dapple = _dapple(rng_crown, (self.camera.height, self.camera.width))
        self.background, self.static_depth = self._paint_static(rng_tex)
        self.static_mask = np.isfinite(self.static_depth)
        self.no_ids = np.zeros(self.static_depth.shape, np.int32)
        self.radius = np.array([math.hypot(v.length / 2, v.width / 2, v.height) + 0.5
                                for v in scene.fleet])
        self.lit, self.lamp_state = self.background, None
        self.exposure = Exposure(rng_exp, scene.fps) if "exposure" in on else None
        self.noise = (NoiseBank(rng_noise, (size[1], size[0], 3), rng_noise.uniform(1.5, 3.5))
                      if "noise" in on else None)

    def _paint_static(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """The empty scene (road plane, far scenery, the street furniture and its shadows) and
        the depth of whatever static thing each pixel shows (inf: the road plane; the far
        scenery counts as a wall at far_m)."""
        scene, cam = self.scene, self.camera
        background, beyond = paint_ground(cam, scene.layout.ground, rng)
        scenery = [Placed(m, m.points, m.face_normal, 0) for m in scene.layout.meshes]
        if self.shadows:
            mask = np.zeros(background.shape[:2], np.uint8)
            for poly in shadow_polygons(cam, scene.light, scenery):
                cv2.fillConvexPoly(mask, poly, 1, cv2.LINE_AA, SHIFT)
            mask[beyond] = 0
            darken(background, mask, scene.light.shadow)
            if not self.sway:
                self._crown_shadows(background, 0.0, beyond)
        buf = Buffers.start(background)
        scenery.sort(key=lambda p: -float(cam.distance(p.world.mean(0))))
        draw_all(buf, cam, scene.light, scenery)
        return buf.image, np.where(beyond, np.float32(scene.layout.ground.far_m), buf.depth)

    def _lamps(self, t: float) -> np.ndarray:
        """The background with the signal lamps lit for time t (redrawn when they change)."""
        signals = self.scene.layout.signals
        if signals is None or not self.scene.layout.lamps:
            return self.background
        state = tuple(signals.state(t).tolist())
        if state != self.lamp_state:
            self.lamp_state, self.lit = state, self.background.copy()
            for lamp in self.scene.layout.lamps:
                cam = self.camera.to_camera(lamp.polygon)
                facing = np.dot(lamp.normal, self.camera.centre - lamp.polygon.mean(0)) > 0
                if state[lamp.group] == lamp.aspect and facing and cam[:, 2].min() > NEAR_M:
                    cv2.fillConvexPoly(self.lit, fixed(self.camera.pixels(cam)),
                                       props.LAMP_COLOURS[lamp.aspect], cv2.LINE_AA, SHIFT)
        return self.lit

    def frames(self) -> Iterator[tuple[np.ndarray, list[Row]]]:
        """(image, rows) per frame: the rows of the vehicles at least partly in view."""
        for n in range(self.scene.frames):
            t = n / self.scene.fps
            base = self._lamps(t)
            buf = Buffers.start(base)
            placed, centres = self._placed(n)
            if self.shadows:
                self._cast_shadows(buf, placed, t)
            seen = []
            for obj, hulls in zip(placed, draw_all(buf, self.camera, self.scene.light, placed)):
                if hulls and _near_view(hulls, self.camera):
                    area, box = silhouette(hulls)
                    seen.append(Seen(obj.ident - 1, area, box, centres[obj.ident - 1]))
            front = cv2.compare(self.static_depth, buf.depth, cv2.CMP_LT)
            cv2.copyTo(base, front, buf.image)             # street furniture in front
            cv2.copyTo(self.no_ids, front, buf.ids)
            np.minimum(buf.depth, self.static_depth, out=buf.depth)
            for crown in self.crowns:
                crown.draw(buf, t, self.sway)
            yield self._camera_out(buf, n, sorted(seen, key=lambda s: s.vehicle))

    def _placed(self, n: int) -> tuple[list[Placed], dict[int, tuple[float, float]]]:
        """The vehicles that may show in frame n, placed, far to near (ident: index + 1),
        and their footprint centres by index."""
        scene = self.scene
        active, centres = scene.centres(n)
        keep = np.nonzero(_in_view(self.camera, centres, self.radius[active]))[0]
        dist = self.camera.distance(np.column_stack([centres[keep], np.ones(len(keep))]))
        keep = keep[np.argsort(-dist, kind="stable")]
        placed = []
        for k, (origin, heading) in zip(active[keep], scene.units(active[keep], n)):
            mesh = scene.fleet[k].mesh
            placed.append(Placed(mesh, *place(mesh, origin, heading), int(k) + 1))
        return placed, {int(active[i]): tuple(centres[i]) for i in keep}

    def _cast_shadows(self, buf: Buffers, placed: list[Placed], t: float) -> None:
        """Darken the road under the shadows of the vehicles (and swaying crowns)."""
        mask = np.zeros(buf.ids.shape, np.uint8)
        for poly in shadow_polygons(self.camera, self.scene.light, placed):
            cv2.fillConvexPoly(mask, poly, 1, cv2.LINE_AA, SHIFT)
        mask[self.static_mask] = 0
        darken(buf.image, mask, self.scene.light.shadow)
        if self.sway:
            self._crown_shadows(buf.image, t, self.static_mask)

    def _crown_shadows(self, image: np.ndarray, t: float, exclude: np.ndarray) -> None:
        """Darken the road (not the `exclude` pixels) under the crowns' shadows at time t:
        dappled by the light through the leaves, and lighter than a solid body's shadow."""
        mask = np.zeros(image.shape[:2], np.uint8)
        for crown in self.crowns:
            poly = crown.shadow(self.camera, self.scene.light, t, self.sway)
            if poly is not None:
                cv2.fillConvexPoly(mask, poly, 1, cv2.LINE_AA, SHIFT)
        mask[exclude] = 0
        x, y, w, h = cv2.boundingRect(mask)
        if w and h:
            leaf = cv2.GaussianBlur(mask[y:y + h, x:x + w] * self.dapple[y:y + h, x:x + w],
                                    (0, 0), 1.0)
            dark = 1 - (1 - math.sqrt(self.scene.light.shadow)) * leaf
            region = image[y:y + h, x:x + w]
            region[:] = (region * dark[..., None]).astype(np.uint8)

    def _camera_out(self, buf: Buffers, n: int, seen: list[Seen]) -> tuple[np.ndarray, list[Row]]:
        """Cut the frame out of the canvas at the shake offset (the image with sub-pixel
        precision, the id buffer to the nearest pixel), apply exposure and noise, and read
        the ground truth off the cut id buffer."""
        w, h = self.scene.layout.camera.width, self.scene.layout.camera.height
        dx, dy = self.margin + self.shake[n]
        ox, oy = int(round(dx)), int(round(dy))
        rows = frame_rows(seen, buf.ids[oy:oy + h, ox:ox + w], (ox, oy))
        img = (cv2.getRectSubPix(buf.image, (w, h), (dx + (w - 1) / 2, dy + (h - 1) / 2))
               if self.margin else buf.image)
        gain = 1.0 if self.exposure is None else self.exposure.gain(float(img[::8, ::8].mean()))
        if self.noise is not None:
            img = cv2.addWeighted(img, gain, self.noise.sample(), 1.0, 0.0, dtype=cv2.CV_8U)
        elif gain != 1.0:
            img = cv2.convertScaleAbs(img, alpha=gain)
        return img, rows


def _dapple(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    """A fixed pattern of sun flecks: the share of sunlight the leaves block (float32, about
    1 under the leaves, 0 in the flecks)."""
    raw = rng.standard_normal((shape[0] // 3 + 2, shape[1] // 3 + 2)).astype(np.float32)
    smooth = cv2.resize(cv2.GaussianBlur(raw, (0, 0), 0.9), shape[::-1],
                        interpolation=cv2.INTER_CUBIC)
    return np.clip(1.6 - 1.8 * smooth / smooth.std(), 0, 1)


def _in_view(camera: Camera, centres: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Which vehicles may show: a ball of `radius` around the footprint centre (raised by
    1 m) in front of the camera whose projection meets the canvas."""
    cam = camera.to_camera(np.column_stack([centres, np.ones(len(centres))]))
    z = cam[:, 2]
    far = z > radius + 0.5
    px = camera.focal * cam[:, :2] / np.where(far, z, 1.0)[:, None]
    reach = camera.focal * radius / np.maximum(z - radius, 0.5)
    inside = ((px[:, 0] + camera.cx + reach >= 0) & (px[:, 0] + camera.cx - reach < camera.width)
              & (px[:, 1] + camera.cy + reach >= 0)
              & (px[:, 1] + camera.cy - reach < camera.height))
    return np.where(far, inside, z > -radius)


def _near_view(hulls: list[np.ndarray], camera: Camera) -> bool:
    """Whether the silhouette's bounding box overlaps the canvas."""
    pts = np.concatenate([p.reshape(-1, 2) for p in hulls]) >> 4
    return bool(pts[:, 0].max() >= 0 and pts[:, 1].max() >= 0 and pts[:, 0].min() < camera.width
                and pts[:, 1].min() < camera.height)


@dataclass(frozen=True)
class ClipResult:
    """What `render_preset` wrote."""

    video: Path
    gt: Path
    world: Path
    calibration: Path
    frames: int
    width: int
    height: int
    vehicles: int
    gt_rows: int
    quality: int
    seconds: float


def render_preset(out_dir: str | os.PathLike, scene: str, frames: int = 300,
                  vehicles: int | None = None, width: int = 640, height: int = 360,
                  fps: float = 25.0, seed: int = 0, quality: int | None = None,
                  nuisances: frozenset[str] = frozenset()) -> ClipResult:
    """Write video.avi, gt.csv, world.csv and calibration.toml of a preset; all atomically."""
    check_settings(frames, 0 if vehicles is None else vehicles, width, height, fps, seed,
                   90 if quality is None else quality)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory")
    started = time.perf_counter()
    sc = build_scene(scene, frames, vehicles, width, height, fps, seed, nuisances)
    if quality is None:
        rng = np.random.default_rng(np.random.SeedSequence([seed, 2]))
        quality = int(rng.integers(30, 71)) if "compression" in nuisances else 90
    renderer = ClipRenderer(sc, seed)
    book = IdBook()
    gt, world = [], []

    def video() -> Iterator[np.ndarray]:
        for n, (image, rows) in enumerate(renderer.frames()):
            for r in rows:
                veh, i = sc.fleet[r.vehicle], book(r.vehicle)
                gt.append((n + 1, i, r.left, r.top, r.width, r.height, 1, -1, -1, -1,
                           r.visible))
                world.append((n + 1, i, *r.centre, 3.6 * sc.motion.v[r.vehicle, n],
                              veh.length, veh.kind))
            yield image

    out.mkdir(parents=True, exist_ok=True)
    write_mjpeg_avi(out / "video.avi", video(), width, height, fps, quality)
    gt_rows = np.array(sorted(gt, key=lambda r: (r[0], r[1])), float).reshape(-1, 11)
    write_text(out / "gt.csv", format_gt(gt_rows))
    write_text(out / "world.csv", format_world(sorted(world, key=lambda r: (r[0], r[1]))))
    cam = sc.layout.camera
    write_text(out / "calibration.toml",
               calibration_toml(cam, choose_landmarks(cam, sc.layout.landmarks)))
    return ClipResult(out / "video.avi", out / "gt.csv", out / "world.csv",
                      out / "calibration.toml", frames, width, height, len(book.ids),
                      len(gt_rows), quality, time.perf_counter() - started)


def render_default(out_dir: str | os.PathLike, scene: str, frames: int = 300,
                   width: int = 640, height: int = 360, fps: float = 25.0,
                   seed: int = 0) -> None:
    """A clip of any scene as `vtrack synth` renders it by default: the overhead road
    (vtrack.sim.traffic, 12 vehicles, no nuisances) or a perspective preset with every
    nuisance."""
    if scene == "overhead":
        from vtrack.sim.traffic import render_scene

        render_scene(out_dir, frames=frames, width=width, height=height, fps=fps, seed=seed)
        return
    from vtrack.sim.nuisance import parse_nuisances

    render_preset(out_dir, scene, frames=frames, width=width, height=height, fps=fps,
                  seed=seed, nuisances=parse_nuisances("all"))


def scored_count_lines(width: int, height: int) -> list[tuple[str, list[float]]]:
    """The counting lines the scene suite and its regression slice score a synthetic clip
    on, (label, [x1, y1, x2, y2]): across the image at 0.6 of its height (as on the real
    clips) and down it at half its width (the overhead and side roads run across)."""
    return [("0.60 H", [0.0, 0.6 * height, width, 0.6 * height]),
            ("0.50 W", [0.5 * width, 0.0, 0.5 * width, height])]
