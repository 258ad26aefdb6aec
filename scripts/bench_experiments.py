"""Wall time of the seed experiments with the Monte Carlo runs stepped together (the harness,
vtrack.estimation.montecarlo) against one run at a time (runs_one_at_a_time: the per-run
loop, each run a one-track filter of the same code), measured in the same process; and the
cost of one update per run of each filter kind, a stack of runs against a loop over one-track
filters.

    .venv/bin/python scripts/bench_experiments.py [--names bearings-2 ...] [--runs 100]
        [--loop-runs N] [--seed 0] [--no-default] [--kinds ekf,iekf,...]
        [--update-runs 100] [--steps 100] [--skip-experiments] [--skip-updates]

Experiments: each at its default number of runs and at --runs, stacked and one run at a
time. The per-run loop is slow (bearings-2 takes minutes per 10 runs); --loop-runs N
measures it at N runs instead and prints the time scaled by runs / N, marked "scaled"
(the per-run loop costs the same per run). Updates: the bearings-2 scenario (two bearing
sensors, Wiener velocity, the toolbox's turning path) over --steps steps of --update-runs
runs; the figure is the mean wall time of update() per run, and the ratio loop / stacked.
On a machine shared with other work, repeat and look at the spread.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import time

import numpy as np

from vtrack.estimation.montecarlo import runs_one_at_a_time
from vtrack.experiments import load_all

UPDATE_KINDS = ("ekf", "iekf", "ukf", "ckf", "iplf", "srukf", "crukf", "ankf1", "ankf2",
                "fuzzy-r", "fuzzy-q", "siim-ekf")


def _timed(fn, *args) -> float:
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        fn(*args)
    return time.perf_counter() - t0


def experiment_times(name: str, runs: int, seed: int, loop_runs: int | None
                     ) -> tuple[float, float, int]:
    """(stacked wall time at `runs`, per-run loop wall time at min(runs, loop_runs), the
    number of runs of the loop measurement)."""
    run = load_all()[name].run
    stacked = _timed(run, runs, seed)
    n_loop = runs if loop_runs is None else min(runs, loop_runs)
    with runs_one_at_a_time():
        loop = _timed(run, n_loop, seed)
    return stacked, loop, n_loop


def bench_experiments(names: list[str], runs: int, seed: int, loop_runs: int | None,
                      default: bool) -> None:
    experiments = load_all()
    totals: dict[str, list[float]] = {}
    for name in names:
        sizes = ([experiments[name].default_runs] if default else []) + [runs]
        for size in dict.fromkeys(sizes):
            stacked, loop, n_loop = experiment_times(name, size, seed, loop_runs)
            loop_full = loop * size / n_loop
            note = "" if n_loop == size else f" ({loop:.1f} s at {n_loop} runs, scaled)"
            print(f"experiment {name} runs {size}: stacked {stacked:.1f} s, one run at a time "
                  f"{loop_full:.1f} s{note}, ratio {loop_full / stacked:.1f}", flush=True)
            if size == runs:
                totals.setdefault("stacked", []).append(stacked)
                totals.setdefault("loop", []).append(loop_full)
    if totals:
        print(f"all {len(names)} experiments at {runs} runs: stacked "
              f"{sum(totals['stacked']):.1f} s, one run at a time {sum(totals['loop']):.1f} s",
              flush=True)


def _bearings_case(runs: int, steps: int):
    from vtrack.estimation.models import Bearings, WienerVelocity
    from vtrack.experiments import _bearings_scenario as scn

    seeds = scn.run_seeds(0, runs)
    Z = scn.measure(scn.turning_truth(seeds), scn.SENSORS_DEDUCED, scn.SIGMA_W, seeds)
    return (WienerVelocity(scn.Q_TRUE), Bearings(scn.SENSORS_DEDUCED, scn.SIGMA_W),
            Z[:, :steps], scn.P0)


def update_cost(kind: str, runs: int, steps: int) -> tuple[float, float]:
    """Mean wall time of one update per run [s]: all runs as one stack, and a loop over one
    filter per run (each predicts and updates alone)."""
    from vtrack.filter_kinds import make_filter

    motion, meas, Z, P0 = _bearings_case(runs, steps)
    x0 = np.zeros(4)

    def stepped(filters: list, z_of) -> float:
        spent = 0.0
        for k in range(Z.shape[1]):
            for i, f in enumerate(filters):
                f.predict(0.01)
                t0 = time.perf_counter()
                f.update(z_of(i, k))
                spent += time.perf_counter() - t0
        return spent

    with np.errstate(all="ignore"):
        ones = [make_filter(kind, motion, meas, x0, P0) for _ in range(runs)]
        t_stack = float("nan")              # a kind without stacks (batched = False)
        if ones[0].batched:
            stack = make_filter(kind, motion, meas, np.tile(x0, (runs, 1)), P0)
            t_stack = stepped([stack], lambda i, k: Z[:, k])
        t_loop = stepped(ones, lambda i, k: Z[i, k])
    n = runs * Z.shape[1]
    return t_stack / n, t_loop / n


def bench_updates(kinds: list[str], runs: int, steps: int) -> None:
    for kind in kinds:
        try:
            stacked, loop = update_cost(kind, runs, steps)
        except Exception as exc:  # noqa: BLE001  (a kind that fails on this scenario)
            print(f"update {kind}: failed ({type(exc).__name__}: {exc})", flush=True)
            continue
        if np.isnan(stacked):
            print(f"update {kind}: runs {runs}: no stack (batched = False), one run at a time "
                  f"{1e3 * loop:.4f} ms per run", flush=True)
            continue
        print(f"update {kind}: runs {runs}: stacked {1e3 * stacked:.4f} ms per run, one run "
              f"at a time {1e3 * loop:.4f} ms, ratio {loop / stacked:.1f}", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--names", nargs="*", help="experiments (default: all)")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--loop-runs", type=int, default=None,
                    help="measure the per-run loop at this many runs and scale")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-default", action="store_true",
                    help="skip the measurement at each experiment's default runs")
    ap.add_argument("--kinds", default=",".join(UPDATE_KINDS))
    ap.add_argument("--update-runs", type=int, default=100)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--skip-experiments", action="store_true")
    ap.add_argument("--skip-updates", action="store_true")
    args = ap.parse_args(argv)
    if not args.skip_updates:
        bench_updates(args.kinds.split(","), args.update_runs, args.steps)
    if not args.skip_experiments:
        names = args.names or sorted(load_all())
        bench_experiments(names, args.runs, args.seed, args.loop_runs, not args.no_default)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
