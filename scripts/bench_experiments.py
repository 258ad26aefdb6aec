"""Wall time of the seed experiments with the Monte Carlo runs stepped together (the harness,
vtrack.estimation.montecarlo, and the INS experiment's batched filter) against one run at a
time (run(runs, seed, batch=False): the per-run loop, each run a one-track filter of the same
code), measured in the same process; the stacked runs on every worker process
(vtrack.estimation.parallel: the filters and cases side by side) against one; and the cost
of one update per run of each filter kind, a stack of runs against a loop over one-track
filters.

    .venv/bin/python scripts/bench_experiments.py [--names bearings-2 ...] [--runs 100]
        [--loop-runs N] [--seed 0] [--no-default] [--kinds ekf,iekf,...]
        [--update-runs 100] [--steps 100] [--skip-experiments] [--skip-updates]

Experiments: each at its default number of runs and at --runs, stacked on the default
workers (parallel.workers(): the CPUs) and on one (VTRACK_WORKERS=1), and one run at a time
on the default workers. The per-run loop is slow (bearings-2 takes minutes per 10 runs);
--loop-runs N measures it at N runs instead and prints the time scaled by runs / N, marked
"scaled" (the per-run loop costs the same per run). Updates: the bearings-2 scenario (two bearing
sensors, Wiener velocity, the toolbox's turning path) over --steps steps of --update-runs
runs; the figure is the mean CPU time of update() per run, and the ratio loop / stacked.
The wall time counts the waits on a machine shared with other work; the CPU time (of the
process and its workers) does not (it still varies with what shares the cores).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import resource
import time

import numpy as np

from vtrack.estimation.parallel import WORKERS_VARIABLE, workers
from vtrack.experiments import load_all

UPDATE_KINDS = ("ekf", "iekf", "ukf", "ckf", "iplf", "srukf", "crukf", "ankf1", "ankf2",
                "fuzzy-r", "fuzzy-q", "siim-ekf")


def _cpu() -> float:
    """CPU seconds of this process and of its ended worker processes."""
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + kids.ru_utime + kids.ru_stime


def _timed(fn, *args) -> tuple[float, float]:
    """(wall, CPU) seconds of fn(*args), its output swallowed."""
    t0, c0 = time.perf_counter(), _cpu()
    with contextlib.redirect_stdout(io.StringIO()):
        fn(*args)
    return time.perf_counter() - t0, _cpu() - c0


@contextlib.contextmanager
def _one_worker():
    """VTRACK_WORKERS=1 inside the block."""
    before = os.environ.get(WORKERS_VARIABLE)
    os.environ[WORKERS_VARIABLE] = "1"
    try:
        yield
    finally:
        if before is None:
            del os.environ[WORKERS_VARIABLE]
        else:
            os.environ[WORKERS_VARIABLE] = before


def experiment_times(name: str, runs: int, seed: int, loop_runs: int | None
                     ) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float],
                                int]:
    """((wall, CPU) stacked at `runs` on the default workers, the same on one worker,
    (wall, CPU) of the per-run loop at min(runs, loop_runs), the number of runs of the loop
    measurement)."""
    run = load_all()[name].run
    stacked = _timed(run, runs, seed)
    with _one_worker():
        alone = _timed(run, runs, seed)
    n_loop = runs if loop_runs is None else min(runs, loop_runs)
    loop = _timed(lambda: run(n_loop, seed, batch=False))
    return stacked, alone, loop, n_loop


def bench_experiments(names: list[str], runs: int, seed: int, loop_runs: int | None,
                      default: bool) -> None:
    experiments = load_all()
    n = workers()
    totals = np.zeros(6)        # stacked wall, CPU; on one worker; loop wall, CPU at `runs`
    for name in names:
        sizes = ([experiments[name].default_runs] if default else []) + [runs]
        for size in dict.fromkeys(sizes):
            stacked, alone, loop, n_loop = experiment_times(name, size, seed, loop_runs)
            scale = size / n_loop
            note = "" if n_loop == size else f" (measured at {n_loop} runs, scaled)"
            print(f"experiment {name} runs {size}: stacked {stacked[0]:.1f} s wall "
                  f"{stacked[1]:.1f} s CPU on {n} workers, {alone[0]:.1f} s wall {alone[1]:.1f} "
                  f"s CPU on 1 (wall ratio {alone[0] / stacked[0]:.2f}), one run at a time "
                  f"{scale * loop[0]:.1f} s wall {scale * loop[1]:.1f} s CPU{note}, CPU ratio "
                  f"{scale * loop[1] / stacked[1]:.1f}", flush=True)
            if size == runs:
                totals += [*stacked, *alone, scale * loop[0], scale * loop[1]]
    if names:
        print(f"all {len(names)} experiments at {runs} runs: stacked {totals[0]:.1f} s wall "
              f"{totals[1]:.1f} s CPU on {n} workers, {totals[2]:.1f} s wall {totals[3]:.1f} s "
              f"CPU on 1 (wall ratio {totals[2] / totals[0]:.2f}), one run at a time "
              f"{totals[4]:.1f} s wall {totals[5]:.1f} s CPU", flush=True)


def _bearings_case(runs: int, steps: int):
    from vtrack.estimation.models import Bearings, WienerVelocity
    from vtrack.experiments import _bearings_scenario as scn

    seeds = scn.run_seeds(0, runs)
    Z = scn.measure(scn.turning_truth(seeds), scn.SENSORS_DEDUCED, scn.SIGMA_W, seeds)
    return (WienerVelocity(scn.Q_TRUE), Bearings(scn.SENSORS_DEDUCED, scn.SIGMA_W),
            Z[:, :steps], scn.P0)


def update_cost(kind: str, runs: int, steps: int) -> tuple[float, float]:
    """Mean CPU time of one update per run [s]: all runs as one stack, and a loop over one
    filter per run (each predicts and updates alone)."""
    from vtrack.filter_kinds import make_filter

    motion, meas, Z, P0 = _bearings_case(runs, steps)
    x0 = np.zeros(4)

    def stepped(filters: list, z_of) -> float:
        spent = 0.0
        for k in range(Z.shape[1]):
            for i, f in enumerate(filters):
                f.predict(0.01)
                t0 = time.process_time()
                f.update(z_of(i, k))
                spent += time.process_time() - t0
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
