#!/usr/bin/env python3
"""Detector recall and precision on real frames with every vehicle boxed
(../shared/videos/realboxes: NGSIM US-101, boxes by García-Aguilar et al. 2021).

Runs `vtrack track VIDEO --save-detections` (default configuration, or --config) on each
sequence, skips the first frames (the background's warm-up, 10 by default as in the
folder's README) and matches detections to the true boxes one to one at IoU >= 0.3
(Hungarian assignment on 1 - IoU, per frame). Prints recall and precision per sequence.

    .venv/bin/python scripts/eval_realboxes.py [--config CFG.toml] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REALBOXES = ROOT.parent / "shared" / "videos" / "realboxes"


def load_boxes(path: Path) -> dict[int, np.ndarray]:
    """frame -> (n, 4) x, y, w, h from a `frame,x,y,w,h` file (a header line allowed)."""
    rows = np.loadtxt(path, delimiter=",", ndmin=2,
                      skiprows=1 if not path.read_text()[:1].isdigit() else 0)
    return {int(f): rows[rows[:, 0] == f, 1:5] for f in np.unique(rows[:, 0])}


def load_detections(path: Path) -> dict[int, np.ndarray]:
    """frame -> (n, 4) boxes of a MOTChallenge detections.csv."""
    if not path.exists() or not path.read_text().strip():
        return {}
    rows = np.loadtxt(path, delimiter=",", ndmin=2)
    return {int(f): rows[rows[:, 0] == f, 2:6] for f in np.unique(rows[:, 0])}


def score(truth: dict[int, np.ndarray], dets: dict[int, np.ndarray], skip: int,
          min_iou: float = 0.3) -> dict[str, float]:
    """Recall and precision over the frames after the first `skip`."""
    from vtrack.evaluation.mot import detected

    n_true = n_det = n_match = 0
    for f, boxes in truth.items():
        if f <= skip:
            continue
        d = dets.get(f, np.zeros((0, 4)))
        n_true, n_det = n_true + len(boxes), n_det + len(d)
        n_match += int(detected(boxes, d, min_iou).sum())
    for f, d in dets.items():   # detections in frames with no true box
        if f > skip and f not in truth:
            n_det += len(d)
    return {"true": n_true, "detections": n_det, "matched": n_match,
            "recall": n_match / max(n_true, 1), "precision": n_match / max(n_det, 1)}


def run(video: Path, out: Path, config: str | None, max_frames: int | None) -> Path:
    from vtrack.cli import main

    args = ["track", str(video), "--out", str(out), "--save-detections", "--quiet"]
    if config:
        args += ["--config", config]
    if max_frames:
        args += ["--max-frames", str(max_frames)]
    if main(args) != 0:
        raise SystemExit(f"error: vtrack track {video} failed")
    return out / "detections.csv"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", help="a TOML config instead of the defaults")
    ap.add_argument("--folder", default=str(REALBOXES), help="the realboxes folder")
    ap.add_argument("--skip", type=int, default=10, help="first frames not scored")
    ap.add_argument("--max-frames", type=int, help="only the first N frames (a quick look)")
    ap.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    args = ap.parse_args()
    folder = Path(args.folder)
    videos = sorted(folder.glob("*.avi"))
    if not videos:
        print(f"error: no realboxes sequences in {folder}", file=sys.stderr)
        return 2
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for video in videos:
            truth = load_boxes(video.with_suffix(".boxes.csv"))
            if args.max_frames:
                truth = {f: b for f, b in truth.items() if f <= args.max_frames}
            dets = load_detections(run(video, Path(tmp) / video.stem, args.config,
                                       args.max_frames))
            results[video.stem] = score(truth, dets, args.skip)
    print(f"{'sequence':<24}{'true':>7}{'dets':>7}{'recall':>8}{'precision':>10}")
    for name, r in results.items():
        print(f"{name:<24}{r['true']:>7}{r['detections']:>7}{r['recall']:>8.3f}"
              f"{r['precision']:>10.3f}")
    print(f"config: {args.config or 'default'}; one-to-one at IoU >= 0.3, frames 1-{args.skip} "
          f"skipped")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
