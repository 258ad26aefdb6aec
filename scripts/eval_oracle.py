#!/usr/bin/env python3
"""The trackers' own ceiling: vtrack's tracker, SORT and ByteTrack fed the ground truth's
boxes as detections, on the scene suite's synthetic clips.

The scene suite (`scripts/eval_suite.py`) scores the detector and the tracker together.
This script takes the detector out. Each frame's detections are the visible ground-truth
boxes: those the scoring counts, visibility >= 0.3. They are whole (amodal) boxes, and may
overlap along the line of sight, which blobs never do. Optionally they are spoiled in a
controlled way:
- each box edge gets Gaussian noise of `--noise` x the box's scale sqrt(w h);
- a share `--drop` of the boxes is dropped at random, each frame independently.
With `--ignore-unmoved` the rows of a vehicle before it first moves (parked, or queued from
the first frame: invisible to background subtraction, and never confirmed by a motion
tracker) are ignore regions (vtrack.evaluation.oracle).
What a tracker loses on these detections is its own loss. The suite's MOTA against this
ceiling tells how much of a clip's loss is the detector's.

vtrack's tracker runs with the default TrackerConfig (or `--config`'s [tracker]), through
`Tracker.step` as `vtrack track` runs it. No detector priors are given, so nothing is split.
`--source appearance` (the default) gives the true boxes as an appearance detector's (whole
vehicles: `seen`, vtrack/tracking/provenance.py), `--source motion` as motion blobs (every
blob heuristic applies); the output's header and the JSON say which.
Scores come from vtrack.evaluation.mot (trackeval), exactly as in the suite.

    .venv/bin/python scripts/eval_oracle.py [--noise 0.05] [--drop 0.1] [--seed 0]
        [--ignore-unmoved] [--source appearance|motion] [--scenes overhead,mast,side,junction] [--seeds 0,1,2]
        [--cache DIR] [--json FILE]

Clips are rendered (or reused) in --cache, the cache of the suite, keyed the same way.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_suite import PEERS, SCENES, SynthClip, peer_rows, render  # noqa: E402

from vtrack.app import config  # noqa: E402
from vtrack.evaluation.mot import evaluate_arrays, read_mot  # noqa: E402
from vtrack.evaluation.oracle import (mot_array, oracle_detections,  # noqa: E402
                                      tracked_rows, unmoved_ignored)
from vtrack.tracking.tracker import Tracker  # noqa: E402

METRICS = ("mota", "idf1", "hota", "id_switches", "false_positives", "misses")


def _mot_columns(dets: np.ndarray) -> np.ndarray:
    """Detections (frame, x, y, w, h) as rows of MOT columns (frame, -1, x, y, w, h, conf 1),
    as the peers take them."""
    return np.column_stack([dets[:, 0], -np.ones(len(dets)), dets[:, 1:5], np.ones(len(dets))])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--noise", type=float, default=0.0,
                    help="std of each box edge, in box scales sqrt(w h)")
    ap.add_argument("--drop", type=float, default=0.0, help="share of boxes dropped")
    ap.add_argument("--seed", type=int, default=0, help="seed of the noise and the drops")
    ap.add_argument("--ignore-unmoved", action="store_true",
                    help="score a vehicle's rows before it first moves half a box scale as "
                         "ignore regions (what a motion detector cannot see)")
    ap.add_argument("--source", choices=("appearance", "motion"), default="appearance",
                    help="the true boxes as an appearance detector's (whole) or as motion "
                         "blobs")
    ap.add_argument("--config", help="a TOML config ([tracker] is used)")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--cache", default="/tmp/vtrack-suite/cache")
    ap.add_argument("--json", metavar="FILE")
    args = ap.parse_args(argv)
    cfg = config.load(args.config)
    trackers = ["vtrack"] + ([] if args.no_peers else list(PEERS))
    clips = [SynthClip(s, int(k), args.frames) for s in args.scenes.split(",")
             for k in args.seeds.split(",")]
    fps = 25.0   # `vtrack synth`'s default, which the suite renders at
    results = []
    print(f"detections: ground truth, edge noise {args.noise:g} box scales, "
          f"drop {args.drop:g}, as {args.source} boxes" + ("; unmoved vehicles ignored" if args.ignore_unmoved else ""))
    print(f"{'clip':12s}" + "".join(f"{t:>24s}" for t in trackers) + "   (MOTA IDF1 HOTA)")
    for clip in clips:
        src = render(clip, Path(args.cache))
        gt = read_mot(src / "gt.csv", max_cols=11)
        scored = unmoved_ignored(gt) if args.ignore_unmoved else gt
        rng = np.random.default_rng(args.seed)
        dets = oracle_detections(gt, args.noise, args.drop, rng)
        frames = int(gt[:, 0].max())
        scores = {}
        for name in trackers:
            rows = (tracked_rows(Tracker(cfg.tracker, clip.width, clip.height, fps), dets,
                                 frames, fps, whole=args.source == "appearance",
                                 video=src / "video.avi")
                    if name == "vtrack" else mot_array(peer_rows(name, _mot_columns(dets),
                                                                 frames, fps)))
            s = evaluate_arrays(scored, rows)
            scores[name] = {k: s[k] for k in METRICS}
        results.append({"clip": clip.name, "scores": scores})
        print(f"{clip.name:12s}" + "".join(
            f"{scores[t]['mota']:8.3f}{scores[t]['idf1']:8.3f}{scores[t]['hota']:8.3f}"
            for t in trackers))
    print("mean        " + "".join(
        "".join(f"{np.mean([r['scores'][t][m] for r in results]):8.3f}"
                for m in ("mota", "idf1", "hota")) for t in trackers))
    if args.json:
        Path(args.json).write_text(json.dumps({"noise": args.noise, "drop": args.drop,
                                               "seed": args.seed, "source": args.source,
                                               "ignore_unmoved": args.ignore_unmoved,
                                               "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
