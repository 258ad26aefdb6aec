"""vtrack report RUN_DIR: one self-contained HTML page from a run's files (INTERFACE.md)."""

from __future__ import annotations

import argparse

NAME = "report"
HELP = "write RUN_DIR/report.html: counts per bin, speeds per class, tracks map, zones"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("run_dir", metavar="RUN_DIR", help="output folder of vtrack track")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")


def run(args: argparse.Namespace) -> int:
    from vtrack.report.page import write_report

    path = write_report(args.run_dir)
    if not args.quiet:
        print(path)
    return 0
