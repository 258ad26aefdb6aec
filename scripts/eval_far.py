#!/usr/bin/env python3
"""Far vehicles: the detector and tracker on 1280x720 mast clips whose far end holds
vehicles under 30 px, with the far band (`[detector] far_band`, vision/far.py) off and on.

Renders `vtrack synth --scene mast` clips at 1280x720 (frames wider than `detect_width`
are halved before MOG2, so their far vehicles are where the far band acts), tracks each
with every configuration given, and prints per clip: the raw detections' recall on the
visible true boxes (visible fraction >= 0.7) and on those under 30 px (sqrt(w h)), their
precision (one to one at IoU >= 0.3, as scripts/eval_realboxes.py), and the tracks'
MOTA, IDF1 and HOTA (vtrack eval). The first `--skip` frames (the warm-up) are not scored
for detection.

    .venv/bin/python scripts/eval_far.py [--seeds 101,102,103,106] [--frames 300]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from vtrack.cli import main as vtrack              # noqa: E402
from vtrack.evaluation.mot import detected, evaluate   # noqa: E402

FAR_PX = 30.0   # a far vehicle: box side sqrt(w h) under this (full-resolution px)
CONFIGS = {"far band off": "[detector]\nfar_band = false\n",
           "far band on": "[detector]\nfar_band = true\n"}


def detection_scores(gt: np.ndarray, dets: np.ndarray, skip: int) -> dict[str, float]:
    """Recall (all visible true boxes, and those under FAR_PX) and precision of the raw
    detections (MOT rows), one to one at IoU >= 0.3, frames after `skip`."""
    n = hit = n_far = hit_far = n_det = matched = 0
    for f in np.unique(gt[:, 0]):
        if f <= skip:
            continue
        truth = gt[(gt[:, 0] == f) & (gt[:, 10] >= 0.7), 2:6]
        boxes = dets[dets[:, 0] == f, 2:6]
        found = detected(truth, boxes, 0.3)
        matched += int(found.sum())
        far = np.sqrt(truth[:, 2] * truth[:, 3]) < FAR_PX
        n, hit = n + len(truth), hit + int(found.sum())
        n_far, hit_far = n_far + int(far.sum()), hit_far + int(found[far].sum())
        n_det += len(boxes)
    return {"recall": hit / max(n, 1), "far_recall": hit_far / max(n_far, 1),
            "far_boxes": n_far, "precision": matched / max(n_det, 1)}


def run_clip(clip: Path, out: Path, config: Path) -> dict[str, float]:
    """Track one rendered clip with `config`; its detection and tracking scores."""
    if vtrack(["track", str(clip / "video.avi"), "--out", str(out), "--config",
               str(config), "--save-detections", "--quiet"]) != 0:
        raise SystemExit(f"error: vtrack track {clip} failed")
    gt = np.loadtxt(clip / "gt.csv", delimiter=",", ndmin=2)
    text = (out / "detections.csv").read_text().strip()
    dets = (np.loadtxt(out / "detections.csv", delimiter=",", ndmin=2) if text
            else np.zeros((0, 10)))
    scores = detection_scores(gt, dets, skip=15)
    track = evaluate(clip / "gt.csv", out / "tracks.csv")
    return scores | {k: float(track[k]) for k in ("mota", "idf1", "hota")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="101,102,103,106",
                    help="mast seeds (these four have far vehicles at 1280x720)")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--work", help="a folder for the clips and runs (default: temporary)")
    ap.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    args = ap.parse_args()
    results: dict[str, dict[str, dict[str, float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.work or tmp)
        work.mkdir(parents=True, exist_ok=True)
        configs = {}
        for i, (name, text) in enumerate(CONFIGS.items()):
            configs[name] = work / f"config{i}.toml"
            configs[name].write_text(text)
        for seed in args.seeds.split(","):
            clip = work / f"mast-{seed}"
            if not (clip / "gt.csv").exists() and vtrack(
                    ["synth", str(clip), "--scene", "mast", "--seed", seed, "--width",
                     "1280", "--height", "720", "--frames", str(args.frames)]) != 0:
                raise SystemExit(f"error: vtrack synth seed {seed} failed")
            results[clip.name] = {name: run_clip(clip, work / f"{clip.name}-{i}", path)
                                  for i, (name, path) in enumerate(configs.items())}
    print(f"{'clip':<12}{'config':<14}{'recall':>8}{'far':>7}{'(boxes)':>9}{'prec.':>7}"
          f"{'MOTA':>8}{'IDF1':>7}{'HOTA':>7}")
    for clip, by_config in results.items():
        for name, r in by_config.items():
            print(f"{clip:<12}{name:<14}{r['recall']:>8.3f}{r['far_recall']:>7.3f}"
                  f"{r['far_boxes']:>9d}{r['precision']:>7.3f}{r['mota']:>8.3f}"
                  f"{r['idf1']:>7.3f}{r['hota']:>7.3f}")
    for name in CONFIGS:
        rows = [by_config[name] for by_config in results.values()]
        print(f"{'mean':<12}{name:<14}"
              + "".join(f"{np.mean([r[k] for r in rows]):>{w}.3f}" for k, w in
                        (("recall", 8), ("far_recall", 7)))
              + f"{'':>9}" + "".join(f"{np.mean([r[k] for r in rows]):>{w}.3f}" for k, w in
                                     (("precision", 7), ("mota", 8), ("idf1", 7),
                                      ("hota", 7))))
    print(f"detections one to one at IoU >= 0.3 (visible >= 0.7; far: side < {FAR_PX:g} px); "
          "tracks: vtrack eval")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
