#!/usr/bin/env python
"""Simulate seed 000's turning target and write a bearings measurement CSV for `vtrack filter`.

The truth is the EKF/UKF toolbox demo's coordinated-turn path (SEEDS.md 2.3): speed 1, start
[0, 0, 1, 0], three quarter-turns of 51 steps each (turn rate (pi/2)/51/dt plus 0.01 N(0,1)
per step), propagated exactly with expm(Fc dt) (in closed form); after each step both sensors measure the
bearing atan2(y - sy, x - sx) + 0.05 N(0,1), wrapped to (-pi, pi]. Row k is at t = (k+1) dt,
so the config's prior (x0, P0) is at t = 0, one dt before the first row.

    python examples/make_bearings_csv.py bearings.csv [--seed 0] [--truth truth.csv]

Writes `t,z0,z1` (one column per sensor); `--truth` also writes `t,x,y,vx,vy`.
"""

from __future__ import annotations

import argparse
import csv
import math

import numpy as np

DT = 0.01
STEPS = 500
SIGMA = 0.05
SENSORS = np.array([[1.0, -2.0], [1.0, 2.0]])  # deduced seed-000 geometry (SEEDS.md 2.3)
TURNS = (slice(49, 100), slice(199, 250), slice(349, 400))  # 0-based, 51 steps each


def turn_transition(a: float, dt: float) -> np.ndarray:
    """expm(Fc dt) for Fc = [[0,0,1,0],[0,0,0,1],[0,0,0,a],[0,0,-a,0]] (the toolbox's
    coordinated turn), in closed form: the velocity turns clockwise at rate a."""
    if a == 0.0:
        return np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    s, c = math.sin(a * dt), math.cos(a * dt)
    return np.array([[1, 0, s / a, (1 - c) / a], [0, 1, -(1 - c) / a, s / a],
                     [0, 0, c, s], [0, 0, -s, c]])


def simulate(seed: int, steps: int = STEPS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (K,), true states (K, 4) and wrapped bearings (K, n_sensors)."""
    rng = np.random.default_rng(seed)
    a = np.zeros(steps)
    for seg in TURNS:
        k = len(a[seg])
        a[seg] = (math.pi / 2) / 51 / DT + 0.01 * rng.standard_normal(k)
    x = np.array([0.0, 0.0, 1.0, 0.0])
    states, bearings = [], []
    for i in range(steps):
        x = turn_transition(a[i], DT) @ x  # propagate first ...
        z = np.arctan2(x[1] - SENSORS[:, 1], x[0] - SENSORS[:, 0])  # ... then measure
        z = z + SIGMA * rng.standard_normal(len(SENSORS))
        bearings.append(np.pi - np.mod(np.pi - z, 2 * np.pi))  # wrap to (-pi, pi]
        states.append(x)
    t = np.round(DT * np.arange(1, steps + 1), 10)
    return t, np.array(states), np.array(bearings)


def _write(path: str, header: list[str], t: np.ndarray, values: np.ndarray) -> None:
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for tk, row in zip(t, values):
            w.writerow([repr(float(tk))] + [repr(float(v)) for v in row])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="measurement CSV to write (t,z0,z1)")
    ap.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ap.add_argument("--steps", type=int, default=STEPS, help=f"steps (default {STEPS})")
    ap.add_argument("--truth", metavar="CSV", help="also write the true states t,x,y,vx,vy")
    args = ap.parse_args()
    t, states, z = simulate(args.seed, args.steps)
    _write(args.out, ["t"] + [f"z{i}" for i in range(z.shape[1])], t, z)
    if args.truth:
        _write(args.truth, ["t", "x", "y", "vx", "vy"], t, states)


if __name__ == "__main__":
    main()
