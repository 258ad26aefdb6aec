"""vtrack experiment NAME: reproduce a seed paper's experiment (INTERFACE.md)."""

from __future__ import annotations

import argparse
import json

from vtrack.errors import InputError

NAME = "experiment"
HELP = "reproduce a seed paper's experiment (Monte Carlo where the paper used it)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.epilog = ("The cases and filters run side by side, one worker process per CPU;\n"
                "the environment variable VTRACK_WORKERS=N sets how many (1: one process).\n"
                "The numbers do not depend on it.")
    p.add_argument("name", nargs="?", help="experiment name (see --list)")
    p.add_argument("--list", action="store_true", help="print the experiment names and exit")
    p.add_argument("--runs", type=int, help="Monte Carlo runs (default: the paper's)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--plot", metavar="FILE.png", help="save a plot (needs matplotlib)")
    p.add_argument("--rerun", metavar="FILE.rrd", help="save a rerun recording of one run")


def run(args: argparse.Namespace) -> int:
    from vtrack.estimation.parallel import workers
    from vtrack.experiments import load_all

    registry = load_all()
    if args.list:
        for name in registry:
            print(name)
        return 0
    if not args.name:
        raise InputError("experiment: give an experiment NAME or --list")
    if args.name not in registry:
        raise InputError(f"experiment: unknown experiment {args.name!r} "
                         f"(known: {', '.join(registry)})")
    if args.runs is not None and args.runs < 1:
        raise InputError("experiment: --runs must be a positive integer")
    try:
        workers()
    except ValueError as exc:
        raise InputError(f"experiment: {exc}") from None
    exp = registry[args.name]
    result = exp.run(args.runs or exp.default_runs, args.seed)
    if args.plot:
        from vtrack.experiments._plot import save_plot

        save_plot(result, exp.name, args.plot)
    if args.rerun:
        from vtrack.viz.rerun_log import log_experiment

        log_experiment(result, exp.name, args.rerun)
    if args.json:
        print(json.dumps(result.summary, sort_keys=True))
    else:
        _print_table(exp.name, result.summary)
    return 0


def _print_table(name: str, summary: dict) -> None:
    def rows(title: str, results: dict) -> None:
        print(f"{title}")
        keys = sorted({k for r in results.values() for k, v in r.items()
                       if isinstance(v, (int, float))})
        print("  " + "kind".ljust(10) + "".join(k.rjust(14) for k in keys))
        for kind, r in results.items():
            cells = "".join((f"{r[k]:14.5g}" if isinstance(r.get(k), (int, float)) else " " * 14)
                            for k in keys)
            print("  " + kind.ljust(10) + cells)

    rows(f"{name}: {summary.get('description', '')}", summary["results"])
    for case, body in summary.get("cases", {}).items():
        rows(f"case {case}: {body.get('description', '')}", body["results"])
