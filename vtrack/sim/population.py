"""Who drives where and when: the vehicles of a perspective scene and their schedule.

The clip's vehicles arrive at uniformly drawn times over its first 90 %, spread over the
scene's routes by their weights times a random factor (so lanes carry different flows).
With `inview`, the flow (at most CAPACITY per entry) runs for WARMUP_S before frame 1, so
that the road is already
busy (and queues stand at red lights) when the video starts; with `parked`, vehicles stand
on the shoulder from the start and pull out during the clip.
"""

from __future__ import annotations

import math

import numpy as np

from vtrack.sim.dynamics import Drivers
from vtrack.sim.scenes import Layout
from vtrack.sim.vehicles import Vehicle, draw_kind, draw_vehicle

WARMUP_S = 35.0
CAPACITY = 0.45            # most vehicles per second one entry lane feeds before frame 1


def draw_flow(rng: np.random.Generator, layout: Layout) -> float:
    """Vehicles per second entering the scene when --vehicles is not given: 0.25-0.65 times
    the square root of the number of entries."""
    entries = len({r.entry for r in layout.routes})
    return rng.uniform(0.25, 0.65) * math.sqrt(entries)


def populate(rng: np.random.Generator, layout: Layout, duration: float, count: int,
             flow: float, inview: bool, parked: bool,
             mix: bool) -> tuple[Drivers, tuple[Vehicle, ...], float]:
    """The drivers (in schedule order), their vehicles and the time the simulation starts:
    `count` vehicles arrive during the clip; before it (inview) `flow` vehicles per second."""
    routes = layout.routes
    share = np.array([r.weight for r in routes]) * rng.uniform(0.4, 1.6, len(routes))
    share /= share.sum()
    span = 0.9 * duration
    times = list(rng.uniform(0, span, count))
    if inview:
        entries = len({r.entry for r in routes})
        rate = min(flow, CAPACITY * entries)
        times += list(rng.uniform(-WARMUP_S, 0, rng.poisson(rate * WARMUP_S)))
    times = np.sort(np.array(times))
    which = rng.choice(len(routes), size=len(times), p=share)
    spots = layout.spots if parked else []
    n = len(spots) + len(times)
    cols: dict[str, list] = {key: [] for key in (
        "path", "entry", "enter_at", "s_start", "stop_s", "stop_group", "release_at",
        "merge_path", "merge_s")}
    entries = max(r.entry for r in routes) + 1
    for j, spot in enumerate(spots):
        for key, value in (("path", spot.path), ("entry", entries + j), ("enter_at", -np.inf),
                           ("s_start", spot.s), ("stop_s", np.inf), ("stop_group", -1),
                           ("release_at", rng.uniform(0.15, 0.6) * duration),
                           ("merge_path", spot.merge_path), ("merge_s", spot.merge_s)):
            cols[key].append(value)
    for t, r in zip(times, which):
        route = routes[r]
        for key, value in (("path", route.path), ("entry", route.entry), ("enter_at", t),
                           ("s_start", 0.0), ("stop_s", route.stop_s),
                           ("stop_group", route.stop_group), ("release_at", -np.inf),
                           ("merge_path", -1), ("merge_s", 0.0)):
            cols[key].append(value)
    fleet = []
    for i in range(n):
        kind = draw_kind(rng, mix, layout.shares)
        if i < len(spots) and kind in ("truck", "motorcycle"):
            kind = "car"
        fleet.append(draw_vehicle(rng, kind, layout.articulated))
    n_dips = rng.choice(3, size=(n, 1), p=[0.4, 0.45, 0.15])
    enter = np.maximum(np.array(cols["enter_at"], float), -WARMUP_S)
    drivers = Drivers(
        np.array(cols["path"], np.int64), np.array(cols["entry"], np.int64),
        np.array(cols["enter_at"], float), np.array(cols["s_start"], float),
        np.array([v.length for v in fleet]), np.array([v.a_max for v in fleet]),
        np.array([v.speed_factor for v in fleet]) * layout.speed_limit,
        enter[:, None] + rng.uniform(2, 14, (n, 2)), rng.uniform(0.5, 2.0, (n, 2)),
        np.where(np.arange(2)[None, :] < n_dips, rng.uniform(0.4, 0.75, (n, 2)), 1.0),
        np.array(cols["stop_s"], float), np.array(cols["stop_group"], np.int64),
        np.array(cols["release_at"], float), np.array(cols["merge_path"], np.int64),
        np.array(cols["merge_s"], float))
    return drivers, tuple(fleet), (-WARMUP_S if inview else 0.0)
