"""vtrack config: print the default configuration (documented TOML) or check a file."""

from __future__ import annotations

import argparse

NAME = "config"
HELP = "print the documented default config (--defaults) or validate a config file"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--defaults", action="store_true", help="print every key with its default")
    p.add_argument("--check", metavar="CFG.toml", help="validate a config file")


def run(args: argparse.Namespace) -> int:
    from vtrack.app import config

    if args.check:
        cfg = config.load(args.check)
        if cfg.calibration:
            from vtrack.analytics.calibration import load_calibration

            load_calibration(cfg.calibration)   # exists and fixes a homography
        print(f"{args.check}: ok (config hash {cfg.digest()})")
        return 0
    print(config.defaults_toml())
    return 0
