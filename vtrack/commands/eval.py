"""`vtrack eval GT.csv TRACKS.csv [--json]`: MOTA, IDF1, HOTA of a tracking result."""

from __future__ import annotations

import argparse
import json

NAME = "eval"
HELP = (
    "Score a tracking result against ground truth (both MOTChallenge CSV): MOTA, IDF1, HOTA,\n"
    "ID switches, false positives, misses. Ground-truth rows whose visible fraction (11th\n"
    "column) is under 0.3, or whose conf is 0, are ignore regions: a tracker box matched to\n"
    "one (IoU >= 0.5) is neither a hit nor a false positive. Needs trackeval:\n"
    "`pip install --no-deps trackeval==1.3.0 tabulate`."
)

_LINES = [
    ("MOTA", "mota", "{:.4f}"), ("IDF1", "idf1", "{:.4f}"), ("HOTA", "hota", "{:.4f}"),
    ("ID switches", "id_switches", "{}"), ("False positives", "false_positives", "{}"),
    ("Misses", "misses", "{}"), ("Precision", "precision", "{:.4f}"),
    ("Recall", "recall", "{:.4f}"), ("GT ids", "gt_ids", "{}"), ("Track ids", "pred_ids", "{}"),
    ("Frames", "frames", "{}"), ("Ignored GT boxes", "ignored_gt_boxes", "{}"),
    ("Ignored track boxes", "ignored_pred_boxes", "{}"),
]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the positional files and --json."""
    parser.add_argument("gt", metavar="GT.csv", help="ground truth (MOT rows, optional 11th "
                        "column: visible fraction)")
    parser.add_argument("tracks", metavar="TRACKS.csv", help="tracker output (MOT rows)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object (fractions, counts) and nothing else")


def run(args: argparse.Namespace) -> int:
    """Evaluate and print the scores as a table or as JSON."""
    from vtrack.evaluation.mot import evaluate

    scores = evaluate(args.gt, args.tracks)
    if args.json:
        print(json.dumps(scores))
    else:
        for label, key, fmt in _LINES:
            print(f"{label:<20}{fmt.format(scores[key])}")
    return 0
