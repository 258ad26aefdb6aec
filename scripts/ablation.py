#!/usr/bin/env python3
"""Ablation: each capability of the detector and tracker switched off alone, on the scene
suite (scripts/eval_suite.py, vtrack only, without the 1280x720 clip unless --large).

    .venv/bin/python scripts/ablation.py [--json ablation.json] [--only NAME,...]

--scenes, --seeds, --frames, --no-real and --cache are handed to eval_suite.py (a smaller
suite, e.g. for a quick check).

Prints one row per configuration: the suite's mean MOTA / IDF1 / HOTA over the synthetic
clips, the worst MOTA, the real clips' counts (in the hand range, within 1, the sum of
the errors) and the synthetic clips' counts against their true counts (exact, within 1,
the sum of the errors), with the differences to the default configuration.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# name -> (what is switched off, the TOML that switches it off)
ABLATIONS = {
    "default": ("nothing (all capabilities on)", ""),
    "no-stabilise": ("camera motion compensation", "[detector]\nstabilise = false\n"),
    "no-background-init": ("background estimated from the video",
                           "[detector]\ninit_background_seconds = 0.0\n"),
    "no-shadows": ("shadow removal (MOG2 shadow label off, as before)",
                   "[detector]\ndetect_shadows = false\n"),
    "no-shift-tolerance": ("foreground a small shift of the background explains dropped",
                           "[detector]\nshift_tolerance = 0.0\n"),
    "hold-standing": ("(switched ON) standing vehicles kept out of MOG2's update (hold.py)",
                      "[detector]\nhold_standing = true\n"),
    "far-floor": ("(switched ON) noise floor in vehicle units where vehicles look small "
                  "(sizes.py)", "[detector]\nmin_vehicle_share = 0.15\n"),
    "no-area-cap": ("the cap on a blob's area (a quarter of the frame)",
                    "[detector]\nmax_area_fraction = 1.0\n"),
    "group-pieces": ("(switched ON) pieces of one tracked vehicle joined in its predicted "
                     "box (pieces.py)", "[detector]\ngroup_pieces = true\n"),
    "area-cap-tracked": ("(switched ON) the area cap only for blobs no predicted box "
                         "explains (pieces.py)", "[detector]\narea_cap_tracked = true\n"),
    "split-footprint": ("(switched ON) blobs longer than two vehicles cut at their waists "
                        "(footprint.py)", "[detector]\nsplit_footprint = true\n"),
    "split-necks": ("(switched ON) blobs pinched into two bodies split at the neck "
                    "(necks.py)", "[detector]\nsplit_necks = true\n"),
    "static-ghosts": ("(switched ON) foreground unchanged for 2 s dropped (ghosts.py)",
                      "[detector]\nstatic_seconds = 2.0\n"),
    "whole-clip-background": ("(switched ON) background estimated over the whole file",
                              "[detector]\ninit_background_seconds = 600.0\n"),
    "no-split": ("merged blobs divided among predicted boxes",
                 "[detector]\nsplit_merged = false\n"),
    "no-gap-labels": ("the gap between two pieces read with MOG2's raw labels",
                      "[tracker]\ngap_labels = false\n"),
    "no-standing": ("standing vehicles held in place", "[tracker]\nstand_speed = 0.0\n"),
    "no-scale-field": ("the scene's scale field (growth predicted from motion)",
                       "[tracker]\nscale_field = false\n"),
    "no-own-size": ("the vehicle's own size restarting a merged or wrong box at once",
                    "[tracker]\nown_size = false\n"),
    "no-size-gate": ("size updated by every detection (no partial-view / merge gating)",
                     "[tracker]\nsize_gate_probability = 0.999999999\n"
                     "size_shrink_seconds = 0.001\n"),
    "no-smoothing": ("coasted stretches smoothed (RTS) once a detection confirms them",
                     "[tracker]\nsmooth_coasted = false\n"),
    "white-fd": ("consistent finite-difference measurement (the seed's white R instead)",
                 "[tracker]\nmeasurement = \"finite-difference-white\"\n"),
}


def run(name: str, toml: str, work: Path, large: bool, suite: list[str] = ()) -> dict:
    """eval_suite.py's vtrack summary with the configuration `toml` (extra arguments
    `suite`)."""
    cfg = work / f"{name}.toml"
    cfg.write_text(toml)
    out = work / f"{name}.json"
    args = [sys.executable, str(ROOT / "scripts" / "eval_suite.py"), "--no-peers",
            "--work", str(work / name), "--json", str(out), *suite]
    if toml:
        args += ["--config", str(cfg)]
    if not large:
        args.append("--no-large")
    proc = subprocess.run(args, check=False, capture_output=True, text=True)
    if not out.exists():
        sys.exit(f"ablation {name}: eval_suite.py failed: {proc.stderr.strip()[-500:]}")
    summary = json.loads(out.read_text())["summary"]
    return summary["vtrack"] | {"recall_moved_mean": summary.get("detector", {}).get(
        "recall_moved_mean", float("nan"))}


def _counts(s: dict, prefix: str) -> str:
    """in range / within 1 / sum of errors of the real (prefix "") or synthetic ("synth_")
    clips' counts; "-" without such clips."""
    keys = (f"{prefix}counts_in_range", f"{prefix}counts_within_1",
            f"{prefix}count_abs_error_sum")
    return "/".join(str(s[k]) for k in keys) if all(k in s for k in keys) else "-"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default="", help="ablation names, comma-separated")
    ap.add_argument("--large", action="store_true", help="include the 1280x720 clip")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    for opt in ("--scenes", "--seeds", "--frames", "--cache"):
        ap.add_argument(opt, help="handed to eval_suite.py")
    ap.add_argument("--no-real", action="store_true", help="handed to eval_suite.py")
    args = ap.parse_args()
    suite = [a for opt in ("scenes", "seeds", "frames", "cache")
             if getattr(args, opt) is not None for a in (f"--{opt}", getattr(args, opt))]
    suite += ["--no-real"] if args.no_real else []
    names = [n for n in ABLATIONS if not args.only or n in args.only.split(",")
             or n == "default"]
    rows = {}
    with tempfile.TemporaryDirectory(prefix="vtrack-ablation-") as tmp:
        for name in names:
            rows[name] = run(name, ABLATIONS[name][1], Path(tmp), args.large, suite)
            print(f"... {name} done", file=sys.stderr, flush=True)
    base = rows["default"]
    print(f"{'switched off':<22}{'MOTA':>7}{'(d)':>8}{'IDF1':>7}{'(d)':>8}{'HOTA':>7}"
          f"{'worst':>8}{'det.rec':>8}{'real counts':>14}{'synth. counts':>16}")
    for name, s in rows.items():
        d = {k: s[k] - base[k] for k in ("mota_mean", "idf1_mean")}
        real, synth = _counts(s, ""), _counts(s, "synth_")
        print(f"{name:<22}{s['mota_mean']:7.3f}{d['mota_mean']:+8.3f}{s['idf1_mean']:7.3f}"
              f"{d['idf1_mean']:+8.3f}{s['hota_mean']:7.3f}{s['mota_worst']:8.3f}"
              f"{s['recall_moved_mean']:8.3f}{real:>14}{synth:>16}")
    print("counts: in range (synthetic: exact) / within 1 / sum of errors; det.rec: the "
          "raw detections' recall on the vehicles once moved, >= 70 % visible")
    if args.json:
        Path(args.json).write_text(json.dumps(
            {n: {"off": ABLATIONS[n][0], **rows[n]} for n in rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
