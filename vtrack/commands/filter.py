"""`vtrack filter CONFIG.toml MEASUREMENTS.csv --out ESTIMATES.csv`: one filter over a log."""

from __future__ import annotations

import argparse

NAME = "filter"
HELP = (
    "Run one filter of the shared estimation core over a recorded measurement log.\n"
    "CONFIG.toml has the sections [motion] (model wiener-velocity | constant-acceleration |\n"
    "unicycle, dt, q), [measurement] (model bearings | position | range | pose, sensors,\n"
    "sigma), [filter] (kind: kf, ekf, iekf, ukf, ckf, iplf, srukf, crukf, ankf1, ankf2,\n"
    "fuzzy-r, fuzzy-q, siim-ekf; plus the kind's optional keys, e.g. alpha, beta, kappa;\n"
    "iekf: max_iterations, tolerance, damped; iplf: rule, max_iterations, tolerance,\n"
    "damped) and\n"
    "[init] (x0, P0). MEASUREMENTS.csv: header t,z0,z1,... (unicycle: then u_v,u_omega);\n"
    "an empty or nan cell is a missing measurement. ESTIMATES.csv: t, the posterior mean\n"
    "x0..x{n-1} and the full posterior covariance P0_0..P{n-1}_{n-1}, one row per input row.\n"
    "--report REPORT.json: the NIS test of the run (sum NIS / sum dof against its 95% band)."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare CONFIG.toml, MEASUREMENTS.csv, --out and --rerun."""
    parser.add_argument("config", metavar="CONFIG.toml", help="models, filter kind and prior")
    parser.add_argument("measurements", metavar="MEASUREMENTS.csv",
                        help="header t,z0,z1,... then one row per step, t increasing")
    parser.add_argument("--out", metavar="ESTIMATES.csv", required=True,
                        help="where to write the posterior means and covariances")
    parser.add_argument("--rerun", metavar="FILE.rrd",
                        help="also save a rerun recording of the run (needs vtrack[rerun])")
    parser.add_argument("--report", metavar="REPORT.json",
                        help="also write the run's NIS consistency test (JSON)")


def run(args: argparse.Namespace) -> int:
    """Parse, filter, write (vtrack.app.filter.filter_files)."""
    from vtrack.app.filter import filter_files

    return filter_files(args.config, args.measurements, args.out, args.rerun, args.report)
