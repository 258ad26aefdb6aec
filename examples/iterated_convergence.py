#!/usr/bin/env python
"""How the iterated kinds' defaults (max_iterations 30, tolerance 1e-4) were chosen.

Runs iekf and iplf with several (max_iterations, tolerance) settings on two bearings cases
of `vtrack experiment bearings-2`: `toolbox-sensors` (the toolbox's sensor pair and turning
truth, where Gauss-Newton converges slowly in a few early updates) and `precise-sensors`
(strongly nonlinear). For each setting it prints the iterations per update (mean, max, how
many updates hit the limit), the position RMSE, and the largest distance of any estimate
from a reference run to convergence (200 iterations, tolerance 1e-10), in posterior
standard deviations.

    python examples/iterated_convergence.py [--runs-toolbox 10] [--runs-precise 30]
"""

from __future__ import annotations

import argparse

import numpy as np

from vtrack.estimation.models import Bearings, WienerVelocity
from vtrack.estimation.montecarlo import monte_carlo, rmse, squared_error
from vtrack.experiments import _bearings_scenario as scn
from vtrack.experiments.bearings import PRECISE
from vtrack.filter_kinds import make_filter

SETTINGS = ((200, 1e-10), (20, 1e-6), (30, 1e-4), (20, 1e-3))   # the first is the reference


def study(name: str, scenario: scn.Scenario, runs: int) -> None:
    case = scn.simulate(scenario, scn.run_seeds(1, runs), {})
    motion = WienerVelocity(scenario.q_filter)
    meas = Bearings(scenario.sensors, scenario.sigma_filter)
    for kind in ("iekf", "iplf"):
        ref = None
        for max_it, tol in SETTINGS:
            run = monte_carlo(
                kind, lambda r: make_filter(kind, motion, meas, case.x0s[r], scenario.prior_cov,
                                            max_iterations=max_it, tolerance=tol),
                case.Z, scenario.dt, record={"iterations": lambda f: f.iterations})
            ref = run if ref is None else ref
            d = run.x - ref.x
            dev = np.sqrt(np.einsum("rki,rkij,rkj->rk", d, np.linalg.inv(ref.P), d)).max()
            it = run.series["iterations"]
            print(f"{name:16s} {kind:5s} max_iterations {max_it:3d} tolerance {tol:7.0e}: "
                  f"iterations mean {it.mean():5.2f} max {it.max():4.0f} at the limit "
                  f"{int((it >= max_it).sum()):3d} of {it.size}; rmse "
                  f"{rmse(squared_error(run.x, case.truth, slice(0, 2))):.6f}; "
                  f"max distance from the reference {dev:.1e} std")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs-toolbox", type=int, default=10)
    ap.add_argument("--runs-precise", type=int, default=30)
    args = ap.parse_args()
    study("toolbox-sensors", scn.Scenario(scn.SENSORS_TOOLBOX), args.runs_toolbox)
    study("precise-sensors", PRECISE, args.runs_precise)


if __name__ == "__main__":
    main()
