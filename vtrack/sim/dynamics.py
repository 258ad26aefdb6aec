"""Vehicles driving along paths: the intelligent driver model with leaders found on the road,
stop lines under a signal cycle, parked vehicles that pull out, and slowing for curves.

Vehicle i's front is at arc length s_i of its path. Its leader is the nearest vehicle whose
front lies ahead on i's path and whose front or rear lies within a corridor of +-CORRIDOR_M
of it (so queues form across paths that share a lane, and a vehicle that turns into a lane
follows the traffic in it); the gap runs to the leader's rear, and the leader's speed counts
along i's path. A red stop line, or an amber one the vehicle
can still stop at with b (v^2 / (2 gap) <= b), is a standing obstacle just past the line; so
is a parked vehicle's own position until its release time, once its lane is clear. The
desired speed is capped for curves of radius r at sqrt(A_LAT r), braking towards it at b:
v_max^2 = A_LAT r + 2 b d at distance d before the arc. Entry follows vtrack.sim.traffic:
a vehicle enters when its slot is due, the vehicles before it at the same entry have
entered and the gap ahead is at least s0 + T v.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vtrack.sim.idm import B_COMFORT, HEADWAY_S, S0_M, advance, desired_speed, idm_command
from vtrack.sim.paths import PathSet

CORRIDOR_M = 1.4           # half-width of the corridor in which a vehicle sees its leader
A_LAT = 2.2                # comfortable lateral acceleration in curves (m/s^2)
STOP_BEFORE_M = 1.0        # vehicles stop this far before a stop line
MERGE_S = 2.5              # a parked vehicle pulls out when traffic is this far (s) away
MAX_DT = 0.05              # longest integration step while frames are recorded (s)
WARMUP_DT = 0.1            # integration step before the first frame (s)


@dataclass(frozen=True)
class Signals:
    """A fixed-time signal cycle: group g is green from green[g, 0] to green[g, 1] (seconds
    into the cycle), amber for `amber` s after, red otherwise; t = 0 is `offset` into it."""

    period: float
    green: np.ndarray      # (G, 2)
    amber: float
    offset: float

    def state(self, t: float) -> np.ndarray:
        """(G,) 0 green, 1 amber, 2 red at time t."""
        c = (t + self.offset) % self.period
        since = (c - self.green[:, 0]) % self.period
        length = (self.green[:, 1] - self.green[:, 0]) % self.period
        return np.where(since < length, 0, np.where(since < length + self.amber, 1, 2))


@dataclass(frozen=True)
class Drivers:
    """Per-vehicle arrays (K,): path and entry, schedule, size and driving parameters."""

    path: np.ndarray
    entry: np.ndarray          # vehicles with one entry go in schedule order
    enter_at: np.ndarray       # -inf: on the road from the start (parked)
    s_start: np.ndarray        # front's arc length when it enters
    length: np.ndarray
    a_max: np.ndarray
    v_desired: np.ndarray
    dip_start: np.ndarray      # (K, 2) speed dips (vtrack.sim.idm.desired_speed)
    dip_hold: np.ndarray
    dip_factor: np.ndarray
    stop_s: np.ndarray         # arc length of its stop line (inf: none)
    stop_group: np.ndarray     # signal group of that line
    release_at: np.ndarray     # parked until then (-inf: not parked)
    merge_path: np.ndarray     # the lane a parked vehicle pulls into (-1: none) ...
    merge_s: np.ndarray        # ... at this arc length of that lane


@dataclass(frozen=True)
class Motion:
    """Sampled motion (K, frames): front arc length s (m), speed v (m/s), acceleration a;
    NaN before the vehicle entered and after it left."""

    s: np.ndarray
    v: np.ndarray
    a: np.ndarray


def simulate(paths: PathSet, d: Drivers, signals: Signals | None, frames: int, fps: float,
             t_start: float) -> Motion:
    """Integrate all vehicles together from t_start (<= 0) and sample at t = n / fps: steps of
    WARMUP_DT before t = 0 (nothing is recorded there), then at most MAX_DT."""
    k = len(d.path)
    out = np.full((3, k, frames), np.nan)
    if k == 0:
        return Motion(*out)
    road = _Road(paths, d, signals)
    for t in np.arange(t_start, 0.0, WARMUP_DT):
        road.step(float(t), min(WARMUP_DT, -float(t)))
    sub = max(1, math.ceil(1.0 / (fps * MAX_DT)))
    dt = 1.0 / (fps * sub)
    for n in range(frames):
        on = road.state == _Road.DRIVING
        out[:, on, n] = road.s[on], road.v[on], road.a[on]
        for i in range(sub):
            road.step((n + i / sub) / fps, dt)
    return Motion(*out)


class _Road:
    """State of every vehicle during the integration, updated together."""

    WAITING, DRIVING, GONE = 0, 1, 2

    def __init__(self, paths: PathSet, d: Drivers, signals: Signals | None) -> None:
        self.paths, self.d, self.signals = paths, d, signals
        k = len(d.path)
        self.prev = _previous_at_entry(d.entry)
        parked = np.isneginf(d.enter_at)
        self.state = np.where(parked, self.DRIVING, self.WAITING).astype(np.int8)
        self.s = np.where(parked, d.s_start, 0.0)
        self.v, self.a = np.zeros(k), np.zeros(k)
        self.held = parked.copy()
        self.exit_s = paths.total[d.path] + d.length
        arcs = paths.k[d.path] != 0
        self.arc_start = np.where(arcs, paths.s0[d.path], np.nan)
        self.arc_end = self.arc_start + paths.len[d.path]
        self.v_curve = np.sqrt(A_LAT / np.where(arcs, np.abs(paths.k[d.path]), 1.0))

    def step(self, t: float, dt: float) -> None:
        """Admit due vehicles, then advance the others by dt under the lagged IDM command
        (only vehicles on the road or due to enter take part)."""
        d = self.d
        on = self.state == self.DRIVING
        before_in = (self.prev < 0) | (self.state[np.maximum(self.prev, 0)] != self.WAITING)
        due = (self.state == self.WAITING) & (t >= d.enter_at) & before_in
        rel = np.nonzero(on | due)[0]
        if len(rel) == 0:
            return
        obst = np.nonzero(on)[0]
        pos = np.where(due[rel], d.s_start[rel], self.s[rel])
        gap, v_lead, s_front, lat_front = self._leaders(rel, obst, pos)
        v_d = np.minimum(desired_speed(d.v_desired[rel], d.dip_start[rel], d.dip_hold[rel],
                                       d.dip_factor[rel], t), self._curve_limit(rel, pos))
        gap, v_lead = self._stops(t, rel, obst, gap, v_lead, s_front, lat_front)
        v_in = np.where(np.isfinite(gap), np.minimum(v_d, v_lead), v_d)
        go = due[rel] & (gap >= S0_M + HEADWAY_S * v_in)
        new = rel[go]
        self.state[new] = self.DRIVING
        self.s[new], self.v[new], self.a[new] = d.s_start[new], v_in[go], 0.0
        drive = on[rel]
        v = self.v[rel]
        dv = np.where(np.isfinite(gap), v - v_lead, 0.0)
        a_cmd = idm_command(v, np.maximum(v_d, 1e-3), np.maximum(gap, 1e-3), dv, d.a_max[rel])
        s_new, v_new, a_new = advance(self.s[rel], v, self.a[rel], a_cmd, dt, drive)
        self.s[rel], self.v[rel], self.a[rel] = s_new, v_new, a_new
        self.state[rel[drive & (s_new >= self.exit_s[rel])]] = self.GONE

    def _leaders(self, rel: np.ndarray, obst: np.ndarray,
                 pos: np.ndarray) -> tuple[np.ndarray, ...]:
        """Gap (m, inf: none) from fronts at `pos` to the nearest obstacle ahead in each
        corridor (its front beyond ours, its front or rear within the corridor; an obstacle
        overlapping us gives a gap of ~0), that obstacle's speed along the path, and the
        obstacles' fronts projected on every path (arc length, lateral; paths x obstacles)."""
        d, paths = self.d, self.paths
        m = len(obst)
        ends = np.concatenate([self.s[obst] - d.length[obst], self.s[obst]])
        pts, heading = paths.pose(np.tile(d.path[obst], 2), ends)
        s_all, lat_all = paths.project(pts)
        if m == 0:
            return (np.full(len(rel), np.inf), np.zeros(len(rel)), s_all, lat_all)
        p = d.path[rel]
        s_rear, lat_rear = s_all[p, :m], lat_all[p, :m]
        s_front, lat_front = s_all[p, m:], lat_all[p, m:]
        ahead = ((np.abs(lat_rear) < CORRIDOR_M) | (np.abs(lat_front) < CORRIDOR_M))
        ahead &= (s_front >= pos[:, None]) & (rel[:, None] != obst[None, :])
        gap = np.where(ahead, np.maximum(s_rear - pos[:, None], 0.05), np.inf)
        j = np.argmin(gap, axis=1)
        best = gap[np.arange(len(rel)), j]
        _, path_heading = paths.pose(p, np.where(np.isfinite(best), pos + best, pos))
        v_lead = self.v[obst[j]] * np.maximum(np.cos(heading[m + j] - path_heading), 0.0)
        return best, np.where(np.isfinite(best), v_lead, 0.0), s_all[:, m:], lat_all[:, m:]

    def _stops(self, t: float, rel: np.ndarray, obst: np.ndarray, gap: np.ndarray,
               v_lead: np.ndarray, s_front: np.ndarray,
               lat_front: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Add red (or stoppable amber) stop lines and parked holds as standing obstacles."""
        d = self.d
        s, v = self.s[rel], self.v[rel]
        to_line = d.stop_s[rel] - STOP_BEFORE_M + S0_M - s
        blocked = np.zeros(len(rel), dtype=bool)
        group = d.stop_group[rel]
        if self.signals is not None:
            light = self.signals.state(t)[np.maximum(group, 0)]
            can_stop = v ** 2 <= 2 * B_COMFORT * np.maximum(to_line - S0_M, 1e-6)
            blocked = ((light == 2) | ((light == 1) & can_stop)) & (group >= 0)
            blocked &= s < d.stop_s[rel] + 0.5
        held = self.held[rel]
        if held.any():
            busy = self._lane_busy(t, rel, obst, s_front, lat_front)
            held &= (t < d.release_at[rel]) | busy
            self.held[rel] = held
        obstacle = np.where(held, d.s_start[rel] + S0_M - s, np.where(blocked, to_line, np.inf))
        closer = obstacle < gap
        return np.where(closer, obstacle, gap), np.where(closer, 0.0, v_lead)

    def _lane_busy(self, t: float, rel: np.ndarray, obst: np.ndarray, s_front: np.ndarray,
                   lat_front: np.ndarray) -> np.ndarray:
        """For each held vehicle: is traffic in its target lane near the merge point (a
        front from w (MERGE_S seconds + 12 m) before it to a car length and 8 m after it)?
        The longer it has waited past its release time, the smaller the gap it accepts:
        w = max(0.35, 1 - wait / 8 s), as drivers in dense traffic squeeze in."""
        d = self.d
        busy = np.zeros(len(rel), dtype=bool)
        for r in np.nonzero(self.held[rel] & (d.merge_path[rel] >= 0))[0]:
            i = rel[r]
            p, m = d.merge_path[i], d.merge_s[i]
            w = max(0.35, 1 - max(t - d.release_at[i], 0.0) / 8.0)
            near = (np.abs(lat_front[p]) < CORRIDOR_M) & (obst != i)
            near &= ((s_front[p] > m - w * (MERGE_S * self.v[obst] + 12.0))
                     & (s_front[p] < m + d.length[i] + 8.0 + d.length[obst]))
            busy[r] = near.any()
        return busy

    def _curve_limit(self, rel: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """Speed cap for the arcs ahead (module docstring); inf on straight roads."""
        start, end = self.arc_start[rel], self.arc_end[rel]
        cap = np.sqrt(self.v_curve[rel] ** 2 + 2 * B_COMFORT * np.maximum(start - pos[:, None],
                                                                          0.0))
        cap = np.where((pos[:, None] > end) | np.isnan(start), np.inf, cap)
        return cap.min(axis=1)


def _previous_at_entry(entry: np.ndarray) -> np.ndarray:
    """Index of the vehicle listed just before each one at its entry (-1: none)."""
    prev = np.full(len(entry), -1)
    last: dict[int, int] = {}
    for i, e in enumerate(entry.tolist()):
        prev[i] = last.get(e, -1)
        last[e] = i
    return prev
