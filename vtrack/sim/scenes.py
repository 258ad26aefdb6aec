"""The perspective scene presets of `vtrack synth`: `mast`, `side` and `junction`.

A preset only decides the layout (vtrack.sim.road), the camera (vtrack.sim.camera), the
paths and where vehicles enter (vtrack.sim.paths), the street furniture (vtrack.sim.props)
and the trees; everything is drawn from the seed. Traffic, dynamics, rendering and ground
truth are shared by all presets.

- mast: a pole or bridge camera 8-30 m up looking down a straight road (1-3 lanes each way)
  at 20-60 degrees; a sign gantry or an overhanging tree hides vehicles.
- side: a camera beside the road, 4-12 m up, looking across it at a shallow angle: the near
  lanes pass in front of the far ones; many long (articulated) trucks.
- junction: a camera on a corner pole over a signalised crossing of two roads: queues wait
  at the stop lines for the green, some vehicles turn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from vtrack.sim import props
from vtrack.sim.camera import Camera
from vtrack.sim.dynamics import Signals
from vtrack.sim.paths import Path
from vtrack.sim.render import Crown
from vtrack.sim.road import WHITE, YELLOW, Ground, Marking, Strip
from vtrack.sim.shapes import Mesh

PRESETS = ("mast", "side", "junction")


@dataclass(frozen=True)
class Route:
    """Traffic entering on `path` at entry point `entry` (one queue per entry), `weight` its
    share of the flow, with a stop line at arc length stop_s under signal group stop_group."""

    path: int
    entry: int
    weight: float
    stop_s: float = math.inf
    stop_group: int = -1


@dataclass(frozen=True)
class Spot:
    """A parking place on the shoulder: the vehicle's path, its front's arc length there, and
    the lane path (and arc length on it) it pulls into."""

    path: int
    s: float
    merge_path: int
    merge_s: float


@dataclass
class Layout:
    """What a preset builds: camera, ground, paths and entries, furniture, trees."""

    camera: Camera
    ground: Ground
    paths: list[Path]
    routes: list[Route]
    speed_limit: float                         # m/s
    spots: list[Spot] = field(default_factory=list)
    signals: Signals | None = None
    meshes: list[Mesh] = field(default_factory=list)
    lamps: list[props.Lamp] = field(default_factory=list)
    crowns: list[Crown] = field(default_factory=list)
    landmarks: list[tuple[float, float]] = field(default_factory=list)
    shares: dict[str, float] = field(default_factory=dict)
    articulated: float = 0.35


def build_layout(name: str, rng: np.random.Generator, width: int, height: int,
                 parked: bool) -> Layout:
    """The layout of preset `name` for a width x height camera."""
    return {"mast": _mast, "side": _side, "junction": _junction}[name](rng, width, height,
                                                                     parked)


# ----------------------------------------------------------------------------- shared parts

def _asphalt(rng: np.random.Generator) -> tuple[float, float, float]:
    """Asphalt from dark and new to pale and worn, slightly warm or cool."""
    grey = rng.uniform(62, 135)
    tint = rng.uniform(-6, 6)
    return (grey + tint, grey, grey - tint)


def _ground(rng: np.random.Generator, strips: list[Strip], urban: bool,
            far: float) -> Ground:
    """Ground colours, patches and the far scenery around the given strips."""
    sky = tuple(np.array((235, 222, 205)) * rng.uniform(0.85, 1.0))
    dry = rng.uniform(0, 1) ** 2                          # lush green .. dry yellow-brown
    grass = tuple((np.array((62, 118, 88)) * (1 - dry) + np.array((92, 138, 150)) * dry)
                  * rng.uniform(0.8, 1.1) + rng.uniform(-6, 6, 3))
    patches = []
    for strip in strips:
        for _ in range(int(rng.integers(0, 4))):
            along = rng.uniform(strip.start + 10, min(strip.end, strip.start + 140))
            across = rng.uniform(strip.right, strip.left)
            x, y = strip.world(along, across)
            patches.append((x, y, rng.uniform(1.5, 8), rng.uniform(0.8, 3.5), strip.heading,
                            rng.choice([0.82, 0.88, 1.1, 1.16])))
    return Ground(tuple(strips), _asphalt(rng), "pavement" if urban else "grass", grass,
                  rng.uniform(2.0, 4.0) if urban else 0.0, far, sky,
                  tuple(np.array((48, 80, 58)) * rng.uniform(0.7, 1.1)), tuple(patches))


def _view_range(camera: Camera, far: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box (min xy, max xy) of the road plane seen by the camera, up to `far`."""
    u, v = np.meshgrid(np.linspace(0, camera.width - 1, 17), np.linspace(0, camera.height - 1, 11))
    rays = camera.rays(u, v).reshape(-1, 3)
    down = rays[:, 2] < -1e-6
    t = -camera.centre[2] / rays[down, 2]
    pts = camera.centre[:2] + t[:, None] * rays[down, :2]
    d = pts - camera.centre[:2]
    dist = np.hypot(d[:, 0], d[:, 1])
    pts = camera.centre[:2] + d * np.minimum(1, far / np.maximum(dist, 1e-9))[:, None]
    return pts.min(0), pts.max(0)


def _pitch_fov(rng: np.random.Generator, pitch: float, aspect: float,
               ratio: float = 2.5) -> float:
    """A horizontal field of view (rad) wide enough that the ground distance grows by
    `ratio` from the bottom to the top image row: sin(p + f) / sin(p - f) >= ratio."""
    lo = 0.0
    for half in np.linspace(0.05, 0.75, 300):
        if pitch - half <= 0.02 or math.sin(pitch + half) / math.sin(pitch - half) >= ratio:
            lo = half
            break
    half_v = max(lo, math.atan(math.tan(rng.uniform(0.45, 0.75)) / aspect))
    return 2 * math.atan(math.tan(half_v) * aspect)


@dataclass(frozen=True)
class _Carriageway:
    """A straight road along X: lane centres and directions, edges and markings."""

    strip: Strip
    lanes: list[tuple[float, int]]           # (y, +1 moving +X / -1 moving -X)
    shoulders: dict[int, float]              # direction -> y of the shoulder's centre
    edges: tuple[float, float]               # y of the outer lane edges (right, left)
    median: float


def _carriageway(rng: np.random.Generator, x0: float, x1: float, per_side: int,
                 parked: bool) -> _Carriageway:
    """Lanes each way, a painted or raised median, shoulders; right- or left-hand traffic."""
    lane = rng.uniform(3.0, 3.75)
    median = 0.0 if rng.random() < 0.4 else rng.uniform(1.2, 4.0)
    keep = 1 if rng.random() < 0.75 else -1        # +1: drive on the right
    shoulder = [rng.uniform(0.4, 3.0), rng.uniform(0.4, 3.0)]
    if parked:
        shoulder = [max(s, rng.uniform(2.6, 3.2)) for s in shoulder]
    inner = median / 2
    lanes = []
    for i in range(per_side):
        y = inner + (i + 0.5) * lane
        lanes += [(-y, keep), (y, -keep)]
    edge_r, edge_l = -(inner + per_side * lane), inner + per_side * lane
    marks = [Marking(edge_r + 0.12, 0.18), Marking(edge_l - 0.12, 0.18)]
    dash = rng.uniform(3.0, 6.0)
    period, phase = dash * rng.uniform(2.0, 3.2), rng.uniform(0, 10)
    for i in range(1, per_side):
        y = inner + i * lane
        marks += [Marking(-y, 0.14, dash, period, phase), Marking(y, 0.14, dash, period, phase)]
    if median == 0.0:
        if rng.random() < 0.5:
            marks += [Marking(-0.12, 0.12, colour=YELLOW), Marking(0.12, 0.12, colour=YELLOW)]
        else:
            marks += [Marking(0.0, 0.15, dash, period, phase)]
    else:
        colour = YELLOW if rng.random() < 0.4 else WHITE
        marks += [Marking(-inner + 0.15, 0.15, colour=colour),
                  Marking(inner - 0.15, 0.15, colour=colour)]
    strip = Strip((0.0, 0.0), 0.0, x0, x1, edge_r - shoulder[0], edge_l + shoulder[1],
                  tuple(y for y, _ in lanes), tuple(marks))
    shoulders = {keep: edge_r - shoulder[0] / 2, -keep: edge_l + shoulder[1] / 2}
    return _Carriageway(strip, lanes, shoulders, (edge_r, edge_l), median)


def _road_traffic(cw: _Carriageway, x0: float, x1: float, spots_x: list[float],
                  parked: bool) -> tuple[list[Path], list[Route], list[Spot]]:
    """One path per lane (entering at the far end of its direction) and the parking spots
    with their pull-out paths into the outer lane."""
    paths, routes = [], []
    for i, (y, d) in enumerate(cw.lanes):
        start, end = (x0, x1) if d > 0 else (x1, x0)
        paths.append(Path.line((start, y), (end, y)))
        routes.append(Route(i, i, 1.0))
    spots = []
    if parked:
        for j, x in enumerate(spots_x):
            d = 1 if j % 2 == 0 else -1
            outer = max((k for k, (_, dd) in enumerate(cw.lanes) if dd == d),
                        key=lambda k: abs(cw.lanes[k][0]))
            y_lane, y_park = cw.lanes[outer][0], cw.shoulders[d]
            start = x0 if d > 0 else x1
            before = abs(x - start)
            path = Path.shift((start, y_park), 0.0 if d > 0 else math.pi, before, y_lane - y_park
                              if d > 0 else y_park - y_lane, 14.0, abs(x1 - x0))
            spots.append(Spot(len(paths), before, outer, before + 14.0))
            paths.append(path)
    return paths, routes, spots


def _verge_plants(rng: np.random.Generator, camera: Camera, x0: float, x1: float,
                  sides: list[tuple[float, int]], count: int) -> tuple[list[Crown], list[Mesh]]:
    """Trees (crown and trunk) and bushes beside the road: sides are (edge y, outward sign).
    None stands so close to the camera that its crown would fill more than a fifth of the
    image width (a plant right at the lens)."""
    crowns, meshes = [], []
    for _ in range(count):
        edge, out = sides[int(rng.integers(len(sides)))]
        x = rng.uniform(x0, x1)
        y = edge + out * rng.uniform(2.5, 14.0)
        colour = tuple(np.array((40, 95, 55)) * rng.uniform(0.7, 1.25))
        sway = rng.uniform(0.05, 0.25)
        tree = rng.random() < 0.55
        r = rng.uniform(1.8, 3.8) if tree else rng.uniform(0.7, 1.5)
        z = rng.uniform(4.0, 7.5) if tree else 0.8 * r
        if 2 * r * camera.focal > 0.2 * camera.width * camera.distance(np.array([x, y, z])):
            continue
        crowns.append(Crown((x, y, z), r, colour, sway if tree else 0.5 * sway))
        if tree:
            meshes.append(props.trunk(x, y, z - 0.6 * r))
    return crowns, meshes


def _dash_corners(cw: _Carriageway, x0: float, x1: float) -> list[tuple[float, float]]:
    """Road-plane landmarks: ends of dashes and points of the edge lines every 5 m."""
    pts = []
    for m in cw.strip.markings:
        if m.dash:
            k0 = math.ceil((x0 - m.phase) / m.period)
            k1 = math.floor((x1 - m.phase) / m.period)
            for k in range(k0, k1 + 1):
                a = m.phase + k * m.period
                pts += [(a, m.offset), (a + m.dash, m.offset)]
        else:
            pts += [(a, m.offset) for a in np.arange(math.ceil(x0 / 5) * 5, x1, 5.0)]
    return pts


# ----------------------------------------------------------------------------- presets

def _mast(rng: np.random.Generator, width: int, height: int, parked: bool) -> Layout:
    """A camera on a pole or a bridge looking down a straight road (module docstring)."""
    per_side = int(rng.choice([1, 2, 3], p=[0.25, 0.45, 0.3]))
    far = rng.uniform(160, 320)
    cw = _carriageway(rng, -200, far + 200, per_side, parked)
    h = rng.uniform(8, 30)
    pitch = math.radians(20 + 40 * rng.uniform() ** 2)
    aim = h / math.tan(pitch)               # the optical axis meets the road this far ahead
    edge = max(abs(e) for e in cw.edges)
    side = aim / 2.5                        # off-axis at most this much: it looks down the road
    if rng.random() < 0.5 or edge + 1.0 > side:                     # on a bridge
        y_cam = rng.uniform(-1, 1) * min(0.8 * edge, side)
    else:                                                          # on a pole beside it
        y_cam = rng.choice([-1, 1]) * rng.uniform(edge + 1.0, min(edge + 5.0, side))
    hfov = _pitch_fov(rng, pitch, width / height)
    focal = (width / 2) / math.tan(hfov / 2)
    yaw = math.atan2(-y_cam, aim) + math.radians(rng.uniform(-6, 6))
    camera = Camera.looking((0.0, y_cam, h), yaw, pitch, math.radians(rng.uniform(-2.5, 2.5)),
                            focal, width, height)
    lo, hi = _view_range(camera, far)
    x0, x1 = min(lo[0], 0.0) - 40, min(hi[0], far) + 25
    spots_x = [rng.uniform(max(lo[0], 5) + 10, max(lo[0], 5) + 0.35 * (hi[0] - lo[0]) + 12)
               for _ in range(int(rng.integers(1, 3)))]
    paths, routes, spots = _road_traffic(cw, x0, x1, spots_x, parked)
    layout = Layout(camera, _ground(rng, [cw.strip], False, far), paths, routes,
                    rng.uniform(70, 115) / 3.6, spots)
    _roadside(rng, layout, cw, lo, hi, far)
    _mast_occluder(rng, layout, cw, lo, hi)
    layout.landmarks = _dash_corners(cw, max(lo[0], 0.0), min(hi[0], far))
    return layout


def _roadside(rng: np.random.Generator, layout: Layout, cw: _Carriageway, lo: np.ndarray,
              hi: np.ndarray, far: float) -> None:
    """Guard rails or a barrier, lamp posts and verge plants of a straight road."""
    x0, x1 = lo[0] - 10, min(hi[0], far) + 10
    right, left = cw.strip.right, cw.strip.left
    if rng.random() < 0.7:
        for y in (right - 0.4, left + 0.4):
            layout.meshes.append(props.guard_rail(x0, x1, y))
    if cw.median >= 1.2:
        layout.meshes.append(props.median_barrier(x0, x1, 0.0))
    side = rng.choice([-1, 1])
    y_post = (right - 1.2) if side < 0 else (left + 1.2)
    gap = rng.uniform(30, 55)
    for x in np.arange(x0 + rng.uniform(0, gap), x1, gap):
        layout.meshes.append(props.lamp_post(x, y_post, -side * rng.uniform(1.5, 3.0)))
    crowns, trunks = _verge_plants(rng, layout.camera, x0, x1, [(right, -1), (left, 1)],
                                   int(rng.integers(6, 16)))
    layout.crowns += crowns
    layout.meshes += trunks


def _ground_point(camera: Camera, u: float, v: float) -> np.ndarray:
    """Road-plane point seen at pixel (u, v)."""
    ray = camera.rays(np.array(u), np.array(v))
    t = -camera.centre[2] / min(ray[2], -1e-6)
    return camera.centre[:2] + t * ray[:2]


def _mast_occluder(rng: np.random.Generator, layout: Layout, cw: _Carriageway,
                   lo: np.ndarray, hi: np.ndarray) -> None:
    """A sign gantry across the road, or a tree overhanging the outer lanes, in mid view."""
    cam = layout.camera
    x = float(_ground_point(cam, cam.width / 2, cam.height * rng.uniform(0.3, 0.55))[0])
    x = min(max(x, lo[0] + 8), layout.ground.far_m * 0.6)
    if rng.random() < 0.6:
        lanes = sorted(y for y, _ in cw.lanes)
        signs = []
        for _ in range(int(rng.integers(1, 4))):
            centre = lanes[int(rng.integers(len(lanes)))]
            signs.append((centre, rng.uniform(2.5, 5.0)))
        layout.meshes.append(props.gantry(rng, x, cw.strip.right, cw.strip.left, signs))
    else:
        side = rng.choice([-1, 1])
        edge = cw.edges[0] if side < 0 else cw.edges[1]
        for dx in (0.0, rng.uniform(6, 12)):
            r = rng.uniform(3.0, 4.5)
            y = edge + side * rng.uniform(0.5, 2.0)
            z = rng.uniform(5.0, 6.5)
            colour = tuple(np.array((38, 92, 50)) * rng.uniform(0.8, 1.2))
            layout.crowns.append(Crown((x + dx, y, z), r, colour, rng.uniform(0.1, 0.25)))
            layout.meshes.append(props.trunk(x + dx, y + side * 1.5, z - 0.5 * r, 0.25))


def _side(rng: np.random.Generator, width: int, height: int, parked: bool) -> Layout:
    """A camera beside the road looking across it (module docstring)."""
    per_side = int(rng.choice([1, 2], p=[0.45, 0.55]))
    far = rng.uniform(140, 260)
    cw = _carriageway(rng, -400, 400, per_side, parked)
    h = rng.uniform(4, 10)
    back = rng.uniform(max(6.0, 1.6 * h), 28)
    y_cam = cw.strip.right - back
    turn = math.radians(rng.uniform(-35, 35))
    yaw = math.pi / 2 + turn
    reach = (-y_cam) / math.cos(turn)
    pitch = math.atan2(h, reach) + math.radians(rng.uniform(-2, 4))
    hfov = math.radians(rng.uniform(32, 62))
    camera = Camera.looking((0.0, y_cam, h), yaw, pitch, math.radians(rng.uniform(-2, 2)),
                            (width / 2) / math.tan(hfov / 2), width, height)
    lo, hi = _view_range(camera, far)
    span = min(hi[0] - lo[0], 2 * far)
    x0, x1 = lo[0] - 40, lo[0] + span + 40
    near = np.linspace(lo[0], lo[0] + span, 7)[1:-1]
    spots_x = [float(near[int(rng.integers(len(near)))]) for _ in range(int(rng.integers(1, 3)))]
    paths, routes, spots = _road_traffic(cw, x0, x1, spots_x, parked)
    layout = Layout(camera, _ground(rng, [cw.strip], False, far), paths, routes,
                    rng.uniform(60, 110) / 3.6, spots,
                    shares={"truck": 0.3, "car": 0.45}, articulated=0.75)
    _roadside(rng, layout, cw, lo, np.array([lo[0] + span, hi[1]]), far)
    for _ in range(int(rng.integers(1, 3))):                      # foreground bushes
        x = rng.uniform(lo[0] + 0.2 * span, lo[0] + 0.8 * span)
        y = rng.uniform(y_cam + 0.35 * back, cw.strip.right - 1.0)
        r = rng.uniform(0.9, 1.8)
        layout.crowns.append(Crown((x, y, 0.8 * r), r,
                                   tuple(np.array((40, 95, 55)) * rng.uniform(0.7, 1.2)),
                                   rng.uniform(0.05, 0.15)))
    layout.landmarks = _dash_corners(cw, lo[0], lo[0] + span)
    return layout


def _junction(rng: np.random.Generator, width: int, height: int, parked: bool) -> Layout:
    """A signalised crossing seen from a corner pole (module docstring)."""
    keep = 1 if rng.random() < 0.75 else -1
    lane = rng.uniform(3.0, 3.6)
    n = [int(rng.choice([1, 2], p=[0.5, 0.5])) for _ in range(2)]
    headings = [0.0, math.pi / 2 + math.radians(rng.uniform(-12, 12))]
    half = [k * lane for k in n]
    arm = 140.0
    sin_x = abs(math.sin(headings[1]))
    strips, paths, routes, landmarks, meshes, lamps = [], [], [], [], [], []
    groups = [0, 1]
    stop_at = []
    for a in range(2):
        other = 1 - a
        stop = (half[other] / sin_x + half[a] * abs(math.cos(headings[1])) / sin_x + 4.5)
        stop_at.append(stop)
    for a in range(2):
        marks = [Marking(-half[a] + 0.12, 0.15), Marking(half[a] - 0.12, 0.15)]
        dash = rng.uniform(2.5, 4.0)
        period = dash * rng.uniform(2, 3)
        for i in range(1, n[a]):
            for sgn in (-1, 1):
                marks.append(Marking(sgn * i * lane, 0.12, dash, period, rng.uniform(0, 5)))
        marks.append(Marking(0.0, 0.15, colour=YELLOW if rng.random() < 0.4 else WHITE))
        s = stop_at[a]
        bars, zebras = [], []
        for sgn in (-1, 1):     # approach from the -along end (sgn -1) or the +along end
            side = (-half[a], 0.0) if sgn * keep < 0 else (0.0, half[a])
            lo_a, hi_a = (-s, -s + 0.45) if sgn < 0 else (s - 0.45, s)
            bars.append((lo_a, hi_a, *side))
            z0 = -s + 0.9 if sgn < 0 else s - 3.9
            zebras.append((z0, z0 + 3.0, -half[a], half[a]))
        strips.append(Strip((0.0, 0.0), headings[a], -arm, arm, -half[a], half[a],
                            tuple(sgn * (i + 0.5) * lane for i in range(n[a])
                                  for sgn in (-1, 1)), tuple(marks), tuple(bars),
                            tuple(zebras)))
    # paths: every lane straight on; the kerb-side lane also turns into the crossing road
    entry = 0
    for a in range(2):
        other = 1 - a
        for d in (1, -1):
            for i in range(n[a]):
                y = -keep * d * (i + 0.5) * lane                  # drive on the `keep` side
                st = strips[a]
                start, end = st.world(-d * arm, y), st.world(d * arm, y)
                s_stop = arm - stop_at[a]
                paths.append(Path.line(start, end))
                routes.append(Route(len(paths) - 1, entry, 0.7, s_stop, groups[a]))
                if i == n[a] - 1:
                    turn = _near_turn(strips, a, other, d, keep, lane, n, arm, stop_at)
                    if turn is not None:
                        paths.append(turn)
                        routes.append(Route(len(paths) - 1, entry, 0.3, s_stop, groups[a]))
                entry += 1
            # the signal for this approach on the kerb side just past the stop line
            st = strips[a]
            pole = st.world(-d * (stop_at[a] - 1.0), -keep * d * (half[a] + 1.2))
            facing = headings[a] + (math.pi if d > 0 else 0.0)
            mesh, lamp = props.signal_head(pole, facing, groups[a])
            meshes.append(mesh)
            lamps += lamp
            landmarks += [st.world(-d * stop_at[a], -half[a]), st.world(-d * stop_at[a], half[a])]
    camera = _corner_camera(rng, width, height, half)
    far = rng.uniform(120, 220)
    ground = _ground(rng, strips, True, far)
    layout = Layout(camera, ground, paths, routes, rng.uniform(40, 60) / 3.6,
                    signals=_signal_plan(rng), meshes=meshes, lamps=lamps, landmarks=landmarks)
    _town(rng, layout, strips, half, ground.pavement_m)
    return layout


def _near_turn(strips: list[Strip], a: int, other: int, d: int, keep: int, lane: float,
               n: list[int], arm: float, stop_at: list[float]) -> Path | None:
    """The kerb-side turn (right with right-hand traffic) from strip a's direction d into
    the crossing strip's outer lane leading away."""
    y_in = -keep * d * (n[a] - 0.5) * lane
    st_a, st_b = strips[a], strips[other]
    # the crossing road's direction that turns towards the kerb side
    heading_in = st_a.heading + (0 if d > 0 else math.pi)
    best = None
    for e in (1, -1):
        heading_out = st_b.heading + (0 if e > 0 else math.pi)
        turn = math.remainder(heading_out - heading_in, 2 * math.pi)
        if turn * keep < 0:          # kerb side: clockwise for right-hand traffic
            best = e
    if best is None:
        return None
    e = best
    y_out = -keep * e * (n[other] - 0.5) * lane
    start = np.array(st_a.world(-d * arm, y_in))
    din = np.array([math.cos(heading_in), math.sin(heading_in)])
    heading_out = st_b.heading + (0 if e > 0 else math.pi)
    dout = np.array([math.cos(heading_out), math.sin(heading_out)])
    p_out = np.array(st_b.world(0.0, y_out))
    # corner: intersection of the incoming line start + t din and outgoing p_out + u dout
    m = np.column_stack([din, -dout])
    t, _ = np.linalg.solve(m, p_out - start)
    corner = start + t * din
    turn_angle = abs(math.remainder(heading_out - heading_in, 2 * math.pi))
    room = t - (arm - stop_at[a]) - 0.5
    radius = float(np.clip(room / math.tan(turn_angle / 2), 3.0, 12.0))
    end = corner + (arm - 10) * dout
    return Path.turn(start, corner, end, radius)


def _corner_camera(rng: np.random.Generator, width: int, height: int,
                   half: list[float]) -> Camera:
    """A pole at one corner of the junction, aimed at (a little past) its centre."""
    qx, qy = rng.choice([-1, 1]), rng.choice([-1, 1])
    x = qx * (half[1] + rng.uniform(4, 14))
    y = qy * (half[0] + rng.uniform(4, 14))
    h = rng.uniform(6, 14)
    aim = np.array([0.0, 0.0]) - np.array([x, y])
    dist = float(np.linalg.norm(aim)) * rng.uniform(1.0, 1.5)
    yaw = math.atan2(aim[1], aim[0]) + math.radians(rng.uniform(-10, 10))
    pitch = math.atan2(h, dist) + math.radians(rng.uniform(-2, 6))
    hfov = math.radians(rng.uniform(60, 90))
    return Camera.looking((x, y, h), yaw, pitch, math.radians(rng.uniform(-2, 2)),
                          (width / 2) / math.tan(hfov / 2), width, height)


def _signal_plan(rng: np.random.Generator) -> Signals:
    """Two groups (one per road) with amber and all-red; the clip starts 3-6 s before one
    group's green, so its queue stands in the first seconds and then drives off."""
    amber, clear = 3.0, 1.5
    g = [rng.uniform(10, 18), rng.uniform(8, 15)]
    period = g[0] + g[1] + 2 * (amber + clear)
    start_b = g[0] + amber + clear
    green = np.array([[0.0, g[0]], [start_b, start_b + g[1]]])
    first = int(rng.integers(2))
    offset = (green[first, 0] - rng.uniform(3, 6)) % period
    return Signals(period, green, amber, offset)


def _town(rng: np.random.Generator, layout: Layout, strips: list[Strip], half: list[float],
          pavement: float) -> None:
    """Buildings in the corners behind the pavements (not where the camera stands), street
    trees and their trunks."""
    a, b = strips
    sin = abs(math.sin(b.heading - a.heading))
    cot = abs(math.cos(b.heading - a.heading)) / sin
    cam_local = a.local(np.array(layout.camera.centre[0]), np.array(layout.camera.centre[1]))
    for sa in (-1, 1):
        for sb in (-1, 1):
            depth, width = rng.uniform(10, 25), rng.uniform(15, 40)
            setback_b = half[0] + pavement + rng.uniform(2, 8)
            setback_a = (half[1] / sin + cot * (setback_b + depth)
                         + pavement + rng.uniform(2, 6))
            mine = np.sign(cam_local[0]) == sa and np.sign(cam_local[1]) == sb
            if rng.random() < 0.8 and not mine:
                corner = a.world(sa * setback_a, sb * setback_b)
                heading = a.heading + (0.0 if sa > 0 else math.pi)
                layout.meshes.append(props.building(rng, corner, heading, width, depth, sa * sb))
            for _ in range(int(rng.integers(0, 3))):
                along = sa * rng.uniform(setback_a - 2, setback_a + 40)
                across = sb * (half[0] + pavement * 0.6)
                x, y = a.world(along, across)
                r, z = rng.uniform(1.8, 3.2), rng.uniform(4.0, 6.0)
                layout.crowns.append(Crown((x, y, z), r, tuple(np.array((40, 95, 55))
                                                               * rng.uniform(0.7, 1.2)),
                                           rng.uniform(0.05, 0.2)))
                layout.meshes.append(props.trunk(x, y, z - 0.6 * r))
