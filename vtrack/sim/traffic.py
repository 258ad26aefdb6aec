"""Synthetic traffic video with exact ground truth (`vtrack synth`).

A static overhead camera looks down at a straight four-lane road: two westbound lanes (moving
left) in the upper half, a median with double yellow lines, two eastbound lanes (moving right)
in the lower half, kerbs, sidewalks and grass. A footbridge crosses the road (with its shadow)
and two trees overhang the outer lanes; both are drawn OVER the vehicles.

Cars, vans and trucks enter from the image border on their lane's side at scheduled times and
follow the intelligent driver model of vtrack.sim.idm (in pixel units). Each vehicle's desired
speed v_d dips for a few seconds at random times, so vehicles brake and speed up again.
Vehicles in one lane never overlap: a vehicle enters only when the gap to its leader is at
least s0 + T v, and IDM keeps that gap.

Ground truth is pure (`simulate_traffic`, `ground_truth`): the footprint of vehicle k at
frame n is the integer box [left, left + length) x [top, top + width) that the renderer
paints; the visible fraction is the share of that footprint that is inside the image and
not under an occluder. Everything is deterministic from the seed.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from vtrack.errors import InputError
from vtrack.fileio import write_text
from vtrack.sim.idm import HEADWAY_S, S0_M, advance, desired_speed, idm_command
from vtrack.sim.nuisance import NoiseBank
from vtrack.sim.output import check_settings, format_gt, write_video

# Road geometry, as fractions of the image height, and real-world scale.
LANE_FRAC = 0.095          # lane width / image height
ROAD_TOP_FRAC = 0.30       # top of the road / image height
LANE_M = 3.5               # a lane is 3.5 m wide: this fixes pixels per metre
SIDEWALK_M = 2.2
KERB_M = 0.35

SUBSTEPS = 4               # integration steps per frame

# Vehicle kinds: (probability, length range m, width range m, desired speed range m/s, a_max).
KINDS = {
    "car": (0.62, (4.1, 4.9), (1.75, 1.95), (11.0, 16.0), 1.5),
    "van": (0.23, (5.2, 6.1), (2.0, 2.2), (10.0, 14.0), 1.1),
    "truck": (0.15, (8.5, 12.0), (2.45, 2.6), (8.5, 12.0), 0.8),
}
PALETTE = np.array([  # BGR body colours
    (235, 235, 235), (192, 192, 188), (38, 36, 35), (84, 84, 80), (40, 40, 185),
    (150, 80, 40), (95, 50, 30), (60, 110, 55), (40, 200, 230), (30, 120, 230),
    (150, 180, 205), (120, 120, 150)], dtype=float)
CARGO = np.array([(228, 230, 230), (200, 200, 196), (170, 110, 60), (60, 60, 170)], dtype=float)


@dataclass(frozen=True)
class Lane:
    """One lane: centre row in pixels and direction (+1 moves right, -1 moves left)."""

    y: float
    direction: int


@dataclass(frozen=True)
class Layout:
    """Static scene geometry in pixels (depends only on the image size)."""

    width: int
    height: int
    px_per_m: float
    road_top: int
    road_bottom: int
    median: tuple[int, int]
    lanes: tuple[Lane, ...]
    bridge: tuple[int, int]                       # footbridge deck columns [x0, x1)
    shadow: tuple[int, int]                       # its shadow columns [x0, x1)
    trees: tuple[tuple[float, float, float], ...]  # crown centre x, y and radius


@dataclass(frozen=True)
class Vehicle:
    """A vehicle's fixed attributes (sizes in whole pixels, colours BGR)."""

    id: int
    kind: str
    lane: int
    length: int
    width: int
    top: int              # first image row of its footprint
    colour: tuple[int, int, int]
    cargo: tuple[int, int, int]


@dataclass(frozen=True)
class Trajectories:
    """Ground-truth motion: arrays (vehicles, frames) along each vehicle's lane.

    s is the distance (pixels) its front has travelled from the entry border, where the
    vehicle is just outside the image; v (px/s) and a (px/s^2) are speed and acceleration.
    All are NaN in frames before the vehicle entered or after it left.
    """

    layout: Layout
    vehicles: tuple[Vehicle, ...]
    fps: float
    s: np.ndarray
    v: np.ndarray
    a: np.ndarray

    @property
    def frames(self) -> int:
        """Number of video frames."""
        return self.s.shape[1]

    def lefts(self) -> np.ndarray:
        """Integer left column of each footprint, (vehicles, frames); garbage where s is NaN."""
        length = np.array([veh.length for veh in self.vehicles], dtype=float)[:, None]
        sign = np.array([self.layout.lanes[veh.lane].direction for veh in self.vehicles])[:, None]
        front = np.where(sign > 0, self.s, self.layout.width - self.s)
        left = np.where(sign > 0, front - length, front)
        return np.floor(np.nan_to_num(left, nan=-1e6) + 0.5).astype(np.int64)


@dataclass(frozen=True)
class SynthResult:
    """What `render_scene` wrote."""

    video: Path
    gt: Path
    frames: int
    width: int
    height: int
    vehicles: int          # distinct vehicles that appear in the video
    gt_rows: int
    seconds: float


# ----------------------------------------------------------------------------- layout

def scene_layout(width: int, height: int) -> Layout:
    """Road, lanes and occluders for a width x height image."""
    lane_px = LANE_FRAC * height
    ppm = lane_px / LANE_M
    road_top = round(ROAD_TOP_FRAC * height)
    median_px = max(2, round(0.7 * ppm))
    median = (road_top + round(2 * lane_px), road_top + round(2 * lane_px) + median_px)
    road_bottom = median[1] + round(2 * lane_px)
    lanes = (Lane(road_top + 0.5 * lane_px, -1), Lane(road_top + 1.5 * lane_px, -1),
             Lane(median[1] + 0.5 * lane_px, 1), Lane(median[1] + 1.5 * lane_px, 1))
    bridge_x = round(0.60 * width)
    bridge = (bridge_x, bridge_x + max(3, round(4.2 * ppm)))
    shadow = (bridge[1], bridge[1] + round(0.5 * (bridge[1] - bridge[0])))
    kerb = (KERB_M + 0.5 * SIDEWALK_M) * ppm
    trees = ((0.2 * width, road_bottom + kerb, 1.15 * lane_px),
             (0.86 * width, road_top - kerb, 0.95 * lane_px))
    return Layout(width, height, ppm, road_top, road_bottom, median, lanes, bridge, shadow, trees)


def occluder_mask(layout: Layout) -> np.ndarray:
    """Boolean (height, width) mask of the pixels drawn over vehicles (bridge, tree crowns)."""
    mask = np.zeros((layout.height, layout.width), dtype=bool)
    mask[:, layout.bridge[0]:layout.bridge[1]] = True
    yy, xx = np.mgrid[0:layout.height, 0:layout.width].astype(float)
    for cx, cy, r in layout.trees:
        theta = np.arctan2(yy - cy, xx - cx)
        edge = r * (1 + 0.07 * np.sin(7 * theta + 1.3) + 0.05 * np.sin(3 * theta + 0.4))
        mask |= np.hypot(xx - cx, yy - cy) < edge
    return mask


# ----------------------------------------------------------------------------- traffic

def simulate_traffic(frames: int, vehicles: int, width: int, height: int, fps: float,
                     seed: int) -> Trajectories:
    """Ground-truth trajectories of `vehicles` scheduled vehicles over `frames` frames (pure)."""
    layout = scene_layout(width, height)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(3)[0])
    fleet = _draw_fleet(rng, vehicles, layout)
    params = _draw_motion(rng, fleet, layout, frames / fps)
    s, v, a = _integrate(fleet, params, layout, frames, fps)
    return Trajectories(layout, fleet, fps, s, v, a)


def _draw_fleet(rng: np.random.Generator, count: int, layout: Layout) -> tuple[Vehicle, ...]:
    names = list(KINDS)
    probs = np.array([KINDS[k][0] for k in names])
    kinds = rng.choice(len(names), size=count, p=probs / probs.sum())
    lanes = rng.permutation(np.resize(np.arange(len(layout.lanes)), count))
    fleet = []
    for i in range(count):
        _, length_m, width_m, _, _ = KINDS[names[kinds[i]]]
        length = max(4, round(rng.uniform(*length_m) * layout.px_per_m))
        wide = max(3, round(rng.uniform(*width_m) * layout.px_per_m))
        offset = rng.uniform(-0.25, 0.25) * layout.px_per_m
        top = math.floor(layout.lanes[lanes[i]].y + offset - wide / 2 + 0.5)
        colour = PALETTE[rng.integers(len(PALETTE))] + rng.uniform(-8, 8, 3)
        cargo = CARGO[rng.integers(len(CARGO))] + rng.uniform(-6, 6, 3)
        fleet.append(Vehicle(i + 1, names[kinds[i]], int(lanes[i]), length, wide, top,
                             _bgr(colour), _bgr(cargo)))
    return tuple(fleet)


def _bgr(colour: np.ndarray) -> tuple[int, int, int]:
    b, g, r = np.clip(np.round(colour), 0, 255).astype(int)
    return int(b), int(g), int(r)


@dataclass(frozen=True)
class _Motion:
    """Per-vehicle motion parameters (pixel units), arrays of length K (events: K x 2)."""

    enter_at: np.ndarray
    v_desired: np.ndarray
    a_max: np.ndarray
    dip_start: np.ndarray
    dip_hold: np.ndarray
    dip_factor: np.ndarray


def _draw_motion(rng: np.random.Generator, fleet: tuple[Vehicle, ...], layout: Layout,
                 duration: float) -> _Motion:
    """Entry schedule (stratified over the clip, some before frame 1) and speed dips."""
    k = len(fleet)
    ppm = layout.px_per_m
    v_des = np.array([rng.uniform(*KINDS[veh.kind][3]) for veh in fleet]) * ppm
    a_max = np.array([KINDS[veh.kind][4] for veh in fleet]) * ppm
    crossing = layout.width / (13.0 * ppm)
    lo, hi = -0.5 * crossing, 0.85 * duration
    enter_at = lo + (np.arange(k) + rng.uniform(0.1, 0.9, k)) * (hi - lo) / max(k, 1)
    n_dips = rng.choice(3, size=(k, 1), p=[0.3, 0.5, 0.2])
    has_dip = np.arange(2)[None, :] < n_dips
    dip_start = enter_at[:, None] + rng.uniform(0.2, 1.0, (k, 2)) * crossing
    dip_hold = rng.uniform(0.5, 2.0, (k, 2))
    dip_factor = np.where(has_dip, rng.uniform(0.3, 0.65, (k, 2)), 1.0)
    return _Motion(enter_at, v_des, a_max, dip_start, dip_hold, dip_factor)


def _leaders(fleet: tuple[Vehicle, ...]) -> np.ndarray:
    """Index of the vehicle scheduled just before each one in its lane (-1: none)."""
    prev = np.full(len(fleet), -1)
    last: dict[int, int] = {}
    for i, veh in enumerate(fleet):
        prev[i] = last.get(veh.lane, -1)
        last[veh.lane] = i
    return prev


def _integrate(fleet: tuple[Vehicle, ...], m: _Motion, layout: Layout, frames: int,
               fps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step all vehicles together; returns s, v, a sampled at the frame times (n / fps)."""
    out = np.full((3, len(fleet), frames), np.nan)
    if not fleet:
        return out[0], out[1], out[2]
    road = _Road(fleet, m, layout)
    for n in range(min(0, math.floor(m.enter_at.min() * fps)), frames):
        if n >= 0:
            on = road.state == 1
            out[:, on, n] = road.s[on], road.v[on], road.a[on]
        for sub in range(SUBSTEPS):
            road.step((n + sub / SUBSTEPS) / fps, 1.0 / (fps * SUBSTEPS))
    return out[0], out[1], out[2]


class _Road:
    """State of every vehicle during the integration (pixel units), updated together."""

    WAITING, DRIVING, GONE = 0, 1, 2

    def __init__(self, fleet: tuple[Vehicle, ...], m: _Motion, layout: Layout) -> None:
        self.m, self.ppm = m, layout.px_per_m
        self.length = np.array([veh.length for veh in fleet], dtype=float)
        self.exit_s = layout.width + self.length
        prev = _leaders(fleet)
        self.has_prev, self.prev = prev >= 0, np.maximum(prev, 0)
        self.s, self.v, self.a = np.zeros((3, len(fleet)))
        self.state = np.full(len(fleet), self.WAITING, dtype=np.int8)

    def step(self, t: float, dt: float) -> None:
        """Admit due vehicles, then advance the others by dt under the lagged IDM command."""
        m = self.m
        v_d = desired_speed(m.v_desired, m.dip_start, m.dip_hold, m.dip_factor, t)
        p = self.prev
        leader_on = self.has_prev & (self.state[p] == self.DRIVING)
        gap = np.where(leader_on, self.s[p] - self.length[p] - self.s, np.inf)
        self._admit(t, v_d, leader_on, gap)
        on = self.state == self.DRIVING
        dv = np.where(leader_on, self.v - self.v[p], 0.0)
        a_cmd = idm_command(self.v, v_d, np.maximum(gap, 1e-6), dv, self.m.a_max, self.ppm)
        self.s, self.v, self.a = advance(self.s, self.v, self.a, a_cmd, dt, on)
        self.state[on & (self.s >= self.exit_s)] = self.GONE

    def _admit(self, t: float, v_d: np.ndarray, leader_on: np.ndarray, gap: np.ndarray) -> None:
        """A due vehicle enters once its leader has entered and left a gap of s0 + T v."""
        v_in = np.where(leader_on, np.minimum(v_d, self.v[self.prev]), v_d)
        room = ~leader_on | (gap >= S0_M * self.ppm + HEADWAY_S * v_in)
        leader_in = ~self.has_prev | (self.state[self.prev] != self.WAITING)
        go = (self.state == self.WAITING) & (t >= self.m.enter_at) & room & leader_in
        self.state[go] = self.DRIVING
        self.s[go], self.v[go], self.a[go] = 0.0, v_in[go], 0.0


# ----------------------------------------------------------------------------- ground truth

def world_rows(traj: Trajectories) -> list[tuple[int, int, float, float, float, float, str]]:
    """world.csv rows (frame, id, X_m, Y_m, speed_kmh, length_m, class): the overhead view is
    a pure scale, so X is the vehicle's front column and Y its lane's centre row below the
    road's top kerb, in metres (`px_per_m`)."""
    ppm = traj.layout.px_per_m
    rows = []
    for k, veh in enumerate(traj.vehicles):
        lane = traj.layout.lanes[veh.lane]
        y = (lane.y - traj.layout.road_top) / ppm
        for n in np.flatnonzero(np.isfinite(traj.s[k])):
            front = traj.s[k, n] if lane.direction > 0 else traj.layout.width - traj.s[k, n]
            rows.append((int(n) + 1, veh.id, front / ppm, y, 3.6 * traj.v[k, n] / ppm,
                         veh.length / ppm, veh.kind))
    return rows


def ground_truth(traj: Trajectories) -> np.ndarray:
    """MOT ground-truth rows (M, 11), sorted by frame then id.

    Columns: frame (1-based), id, left, top, width, height (footprint clipped to the image),
    conf 1, x, y, z = -1, and the visible fraction of the full footprint (inside the image
    and not under an occluder).
    """
    lay = traj.layout
    length = np.array([veh.length for veh in traj.vehicles], dtype=np.int64)[:, None]
    wide = np.array([veh.width for veh in traj.vehicles], dtype=np.int64)[:, None]
    top = np.array([veh.top for veh in traj.vehicles], dtype=np.int64)[:, None]
    left = traj.lefts()
    x0, x1 = np.clip(left, 0, lay.width), np.clip(left + length, 0, lay.width)
    y0, y1 = np.clip(top, 0, lay.height), np.clip(top + wide, 0, lay.height)
    present = ~np.isnan(traj.s) & (x1 > x0) & (y1 > y0)
    x0, x1, y0, y1 = (np.broadcast_to(c, present.shape) for c in (x0, x1, y0, y1))
    sat = _visible_table(lay)
    visible = sat[y1, x1] - sat[y0, x1] - sat[y1, x0] + sat[y0, x0]
    frac = visible / (length * wide)
    ids = np.array([veh.id for veh in traj.vehicles])
    n_idx, k_idx = np.nonzero(present.T)
    cols = [n_idx + 1, ids[k_idx], x0[k_idx, n_idx], y0[k_idx, n_idx],
            (x1 - x0)[k_idx, n_idx], (y1 - y0)[k_idx, n_idx], np.ones(len(n_idx)),
            *(-np.ones((3, len(n_idx)))), frac[k_idx, n_idx]]
    return np.column_stack(cols).astype(float) if len(n_idx) else np.zeros((0, 11))


def _visible_table(layout: Layout) -> np.ndarray:
    """Summed-area table of the non-occluded pixels, shape (height + 1, width + 1)."""
    sat = np.zeros((layout.height + 1, layout.width + 1), dtype=np.int64)
    sat[1:, 1:] = (~occluder_mask(layout)).cumsum(0).cumsum(1)
    return sat


# ----------------------------------------------------------------------------- rendering

class Renderer:
    """Paints the frames of a trajectory set: background, vehicles, shadow, occluders, noise."""

    NOISE_SIGMA = 2.5      # per-pixel sensor noise (grey levels)
    FLICKER = 0.02         # amplitude of the global brightness flicker

    def __init__(self, traj: Trajectories, seed: int) -> None:
        texture_seq, noise_seq = np.random.SeedSequence(seed).spawn(3)[1:]
        self.traj = traj
        rng = np.random.default_rng(texture_seq)
        self.background = _paint_background(traj.layout, rng)
        self.mask = occluder_mask(traj.layout)
        self.occluders = _paint_occluders(traj.layout, rng)
        self.sprites = [_sprite(veh, traj.layout.lanes[veh.lane].direction)
                        for veh in traj.vehicles]
        self._lefts = traj.lefts()
        self._noise_rng = np.random.default_rng(noise_seq)
        self._noise = NoiseBank(self._noise_rng, self.background.shape, self.NOISE_SIGMA)
        self._phase = rng.uniform(0, 2 * np.pi)

    def empty(self) -> np.ndarray:
        """The scene without vehicles and without noise (uint8 BGR)."""
        return self._finish(self.background.copy())

    def clean(self, n: int) -> np.ndarray:
        """Frame n (0-based) with its vehicles, before noise and flicker (uint8 BGR)."""
        img = self.background.copy()
        for k, veh in enumerate(self.traj.vehicles):
            if not np.isnan(self.traj.s[k, n]):
                _blit(img, self.sprites[k], int(self._lefts[k, n]), veh.top)
        return self._finish(img)

    def frames(self) -> Iterator[np.ndarray]:
        """All frames in order, with sensor noise and flicker (deterministic from the seed)."""
        for n in range(self.traj.frames):
            gain = 1 + self.FLICKER * math.sin(2 * math.pi * n / (4.1 * self.traj.fps)
                                               + self._phase)
            gain += 0.004 * self._noise_rng.standard_normal()
            img = self.clean(n).astype(np.float32)
            img *= np.float32(gain)
            img += self._noise.sample()
            np.clip(img, 0, 255, out=img)
            yield img.astype(np.uint8)

    def _finish(self, img: np.ndarray) -> np.ndarray:
        x0, x1 = self.traj.layout.shadow
        img[:, x0:x1] = (img[:, x0:x1] * 0.62).astype(np.uint8)
        np.copyto(img, self.occluders, where=self.mask[:, :, None])
        return img


def _blit(img: np.ndarray, sprite: np.ndarray, left: int, top: int) -> None:
    """Copy a sprite into img at (left, top), clipped to the image."""
    h, w = sprite.shape[:2]
    x0, y0 = max(left, 0), max(top, 0)
    x1, y1 = min(left + w, img.shape[1]), min(top + h, img.shape[0])
    if x1 > x0 and y1 > y0:
        img[y0:y1, x0:x1] = sprite[y0 - top:y1 - top, x0 - left:x1 - left]


def _sprite(veh: Vehicle, direction: int) -> np.ndarray:
    """Top view of a vehicle, (width, length, 3) uint8, facing its direction of travel."""
    length, wide = veh.length, veh.width
    body = np.array(veh.colour, dtype=float)
    img = np.empty((wide, length, 3))
    img[:] = body
    glass = np.array((48, 42, 38), dtype=float)
    col = lambda f: int(round(f * length))  # noqa: E731  (fraction of length -> column)
    if veh.kind == "truck":
        img[:, :col(0.78)] = veh.cargo
        img[:, col(0.78):col(0.80)] = (50, 50, 50)
        for x in range(col(0.08), col(0.78), max(2, col(0.09))):
            img[:, x] = np.array(veh.cargo) * 0.85
        img[1:-1, col(0.88):col(0.95)] = glass
    elif veh.kind == "van":
        img[1:-1, col(0.08):col(0.74)] = body * 0.93 + 12
        img[1:-1, col(0.74):col(0.86)] = glass
    else:
        img[1:-1, col(0.18):col(0.28)] = glass
        img[1:-1, col(0.30):col(0.56)] = body * 0.9 + 10
        img[1:-1, col(0.56):col(0.71)] = glass
    img[[0, -1], :] *= 0.55
    img[:, [0, -1]] *= 0.55
    if wide >= 5:
        img[[1, wide - 2], -1] = (200, 240, 250)                      # headlights
        img[[1, wide - 2], 0] = (40, 40, 190)                         # tail lights
    sprite = np.clip(img, 0, 255).astype(np.uint8)
    return sprite if direction > 0 else sprite[:, ::-1].copy()


def _noise_field(rng: np.random.Generator, shape: tuple[int, int], scale: int) -> np.ndarray:
    """Smooth zero-mean, unit-ish noise: coarse Gaussian noise upsampled by `scale`."""
    h, w = shape
    coarse = rng.standard_normal((h // scale + 2, w // scale + 2)).astype(np.float32)
    return cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)


def _paint_background(lay: Layout, rng: np.random.Generator) -> np.ndarray:
    """Grass, sidewalks, kerbs, asphalt with texture, and lane markings (uint8 BGR)."""
    h, w, ppm = lay.height, lay.width, lay.px_per_m
    shape = (h, w)
    grain = rng.standard_normal(shape).astype(np.float32)
    img = np.empty((h, w, 3), dtype=np.float32)
    img[:] = (60, 128, 72)                                            # grass
    img += (14 * _noise_field(rng, shape, 12) + 4 * grain)[:, :, None] * (0.6, 1.0, 0.7)
    kerb, walk = max(1, round(KERB_M * ppm)), round(SIDEWALK_M * ppm)
    for y0, y1 in ((lay.road_top - kerb - walk, lay.road_top - kerb),
                   (lay.road_bottom + kerb, lay.road_bottom + kerb + walk)):
        img[max(y0, 0):max(y1, 0)] = (168, 170, 166)                   # sidewalk
        img[max(y0, 0):max(y1, 0)] += 3 * grain[max(y0, 0):max(y1, 0), :, None]
        for x in range(0, w, max(3, round(1.5 * ppm))):
            img[max(y0, 0):max(y1, 0), x] *= 0.82                    # paving joints
    img[lay.road_top - kerb:lay.road_top] = (205, 205, 203)           # kerbs
    img[lay.road_bottom:lay.road_bottom + kerb] = (205, 205, 203)
    road = slice(lay.road_top, lay.road_bottom)
    stains = 7 * _noise_field(rng, shape, 20) + 4 * cv2.GaussianBlur(grain, (3, 3), 0.7)
    img[road] = np.array((98, 96, 92), dtype=np.float32) + stains[road, :, None]
    _paint_markings(img, lay, rng)
    return np.clip(img, 0, 255).astype(np.uint8)


def _paint_markings(img: np.ndarray, lay: Layout, rng: np.random.Generator) -> None:
    """Edge lines, dashed lane lines and the double yellow median lines (in place)."""
    ppm, w = lay.px_per_m, lay.width
    thick = max(1, round(0.15 * ppm))
    wear = 0.85 + 0.15 * rng.random((img.shape[0], w, 1)).astype(np.float32)
    white, yellow = np.array((225, 228, 228)), np.array((40, 190, 225))

    def paint(y: int, colour: np.ndarray, xs: slice = slice(None)) -> None:
        img[y:y + thick, xs] = colour * wear[y:y + thick, xs]

    inset = max(1, round(0.3 * ppm))
    paint(lay.road_top + inset, white)
    paint(lay.road_bottom - inset - thick, white)
    paint(lay.median[0], yellow)
    paint(lay.median[1] - thick, yellow)
    dash, period = round(3 * ppm), round(9 * ppm)
    for a, b in ((lay.lanes[0], lay.lanes[1]), (lay.lanes[2], lay.lanes[3])):
        y = round(0.5 * (a.y + b.y) - thick / 2)
        for x in range(round(2 * ppm), w, max(period, 2)):
            paint(y, white, slice(x, x + dash))


def _paint_occluders(lay: Layout, rng: np.random.Generator) -> np.ndarray:
    """The footbridge deck and tree crowns as a full image (used only under the mask)."""
    h, w, ppm = lay.height, lay.width, lay.px_per_m
    grain = rng.standard_normal((h, w)).astype(np.float32)
    img = np.empty((h, w, 3), dtype=np.float32)
    img[:] = (172, 176, 178)                                          # concrete deck
    img += 3 * grain[:, :, None]
    x0, x1 = lay.bridge
    rail = max(1, round(0.25 * ppm))
    img[:, x0:x0 + rail] = (70, 72, 75)
    img[:, x1 - rail:x1] = (70, 72, 75)
    for y in range(0, h, max(3, round(2.5 * ppm))):
        img[y, x0 + rail:x1 - rail] *= 0.85                           # deck joints
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    leaves = 22 * _noise_field(rng, (h, w), max(2, round(0.8 * ppm))) + 5 * grain
    for cx, cy, r in lay.trees:
        near = np.hypot(xx - cx, yy - cy) < 1.2 * r
        shade = 1.15 - 0.45 * np.clip(np.hypot(xx - cx, yy - cy) / r, 0, 1)
        crown = np.array((38, 96, 44), dtype=np.float32) * shade[:, :, None]
        crown += leaves[:, :, None] * (0.5, 1.0, 0.6)
        img[near] = crown[near]
    return np.clip(img, 0, 255).astype(np.uint8)


# ----------------------------------------------------------------------------- output

def render_scene(out_dir: str | os.PathLike, frames: int = 300, vehicles: int = 12,
                 width: int = 640, height: int = 360, fps: float = 25.0, seed: int = 0,
                 quality: int = 90) -> SynthResult:
    """Write OUT_DIR/video.avi (MJPG at `quality`) and OUT_DIR/gt.csv; both atomically."""
    check_settings(frames, vehicles, width, height, fps, seed, quality)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory")
    started = time.perf_counter()
    traj = simulate_traffic(frames, vehicles, width, height, fps, seed)
    rows = ground_truth(traj)
    out.mkdir(parents=True, exist_ok=True)
    write_video(out / "video.avi", Renderer(traj, seed).frames(), width, height, fps, quality)
    write_text(out / "gt.csv", format_gt(rows))
    return SynthResult(out / "video.avi", out / "gt.csv", frames, width, height,
                       len(np.unique(rows[:, 1])), len(rows), time.perf_counter() - started)
