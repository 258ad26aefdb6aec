"""Speed, length and class of a calibrated run against a synthetic scene's world ground truth.

    .venv/bin/python scripts/eval_speed.py SYNTH_DIR RUN_DIR [--json] [--min-iou 0.3]

SYNTH_DIR holds gt.csv (MOT boxes of the true vehicles) and world.csv
(`frame,id,X_m,Y_m,speed_kmh,length_m,class`), e.g. from `vtrack synth --scene mast`; RUN_DIR
is `vtrack track SYNTH_DIR/video.avi --calibration SYNTH_DIR/calibration.toml --out RUN_DIR`.

Matching: in every frame the run's boxes (tracks.csv) are assigned to the true boxes by
maximum IoU (Hungarian, IoU >= --min-iou); a track belongs to the true vehicle it was assigned
to most often, and a true vehicle is represented by the longest track that belongs to it.
Per matched vehicle: the speed error is vehicles.csv speed_mean_kmh minus the mean of the true
speed over the frames the track was matched to it (the same stretch of road); the maximum is
compared with the true maximum over those frames; length and class against world.csv.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from vtrack.evaluation.mot import box_iou, read_mot

CLASSES = ("motorcycle", "car", "van", "truck")


def _world(path: Path) -> dict[int, dict]:
    """Per true id: {frame: speed_kmh}, length_m, class."""
    out: dict[int, dict] = {}
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            v = out.setdefault(int(r["id"]), {"speed": {}, "length": float(r["length_m"]),
                                              "class": r["class"]})
            v["speed"][int(r["frame"])] = float(r["speed_kmh"])
    return out


def _vehicles(path: Path) -> dict[int, dict]:
    with open(path, newline="") as fh:
        return {int(r["id"]): r for r in csv.DictReader(fh)}


def match_tracks(gt: np.ndarray, tracks: np.ndarray, min_iou: float
                 ) -> dict[int, tuple[int, list[int]]]:
    """true id -> (track id, frames the track was assigned to it) for the longest track."""
    frames_of: dict[tuple[int, int], list[int]] = defaultdict(list)
    for f in np.intersect1d(np.unique(gt[:, 0]), np.unique(tracks[:, 0])):
        g, t = gt[gt[:, 0] == f], tracks[tracks[:, 0] == f]
        iou = box_iou(g[:, 2:6], t[:, 2:6])
        rows, cols = linear_sum_assignment(-iou)
        for i, j in zip(rows, cols):
            if iou[i, j] >= min_iou:
                frames_of[(int(g[i, 1]), int(t[j, 1]))].append(int(f))
    owner: dict[int, tuple[int, int]] = {}           # track -> (true id, frames)
    for (gid, tid), frames in frames_of.items():
        if tid not in owner or len(frames) > owner[tid][1]:
            owner[tid] = (gid, len(frames))
    best: dict[int, tuple[int, list[int]]] = {}
    for tid, (gid, n) in owner.items():
        if gid not in best or n > len(best[gid][1]):
            best[gid] = (tid, sorted(frames_of[(gid, tid)]))
    return best


def _num(text: str) -> float:
    return float(text) if text not in ("", None) else float("nan")


def evaluate(synth: Path, run: Path, min_iou: float = 0.3) -> dict:
    gt = read_mot(synth / "gt.csv")
    tracks = read_mot(run / "tracks.csv")
    world = _world(synth / "world.csv")
    vehicles = _vehicles(run / "vehicles.csv")
    best = match_tracks(gt, tracks, min_iou)
    per = []
    for gid in sorted(world):
        if gid not in best:
            per.append({"gt_id": gid, "track_id": None, "class_true": world[gid]["class"]})
            continue
        tid, frames = best[gid]
        w, v = world[gid], vehicles.get(tid, {})
        speeds = [w["speed"][f] for f in frames if f in w["speed"]]
        true_mean = float(np.mean(speeds)) if speeds else float("nan")
        true_max = float(np.max(speeds)) if speeds else float("nan")
        per.append({
            "gt_id": gid, "track_id": tid, "frames": len(frames),
            "speed_true_kmh": round(true_mean, 2),
            "speed_kmh": _num(v.get("speed_mean_kmh", "")),
            "speed_error_kmh": round(_num(v.get("speed_mean_kmh", "")) - true_mean, 2),
            "max_error_kmh": round(_num(v.get("speed_max_kmh", "")) - true_max, 2),
            "length_true_m": w["length"], "length_m": _num(v.get("length_m", "")),
            "length_error_m": round(_num(v.get("length_m", "")) - w["length"], 2),
            "class_true": w["class"], "class": v.get("class", ""),
        })
    return {"vehicles": per, **summarise(per)}


def summarise(per: list[dict]) -> dict:
    """RMSE, bias and error percentiles over the matched vehicles; class accuracy and the
    confusion matrix (rows: true class)."""
    m = [p for p in per if p["track_id"] is not None]
    e = np.array([p["speed_error_kmh"] for p in m], dtype=float)
    mx = np.array([p["max_error_kmh"] for p in m], dtype=float)
    le = np.array([p["length_error_m"] for p in m], dtype=float)
    e, mx, le = e[np.isfinite(e)], mx[np.isfinite(mx)], le[np.isfinite(le)]

    def stats(x: np.ndarray) -> dict:
        if not len(x):
            return {}
        q = np.percentile(x, [5, 25, 50, 75, 95])
        return {"rmse": round(float(np.sqrt(np.mean(x ** 2))), 3),
                "bias": round(float(np.mean(x)), 3),
                "abs_max": round(float(np.max(np.abs(x))), 3),
                "p5_p25_p50_p75_p95": [round(float(v), 3) for v in q]}

    confusion = {c: Counter() for c in CLASSES}
    for p in m:
        confusion.setdefault(p["class_true"], Counter())[p["class"] or "none"] += 1
    correct = sum(p["class"] == p["class_true"] for p in m)
    return {
        "gt_vehicles": len(per), "matched": len(m),
        "speed_error_kmh": stats(e),
        "speed_within_5kmh": round(float(np.mean(np.abs(e) <= 5)), 3) if len(e) else None,
        "max_speed_error_kmh": stats(mx),
        "length_error_m": stats(le),
        "class_accuracy": round(correct / len(m), 3) if m else None,
        "confusion": {k: dict(v) for k, v in confusion.items() if v},
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("synth", type=Path)
    p.add_argument("run", type=Path)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--min-iou", type=float, default=0.3)
    a = p.parse_args(argv)
    res = evaluate(a.synth, a.run, a.min_iou)
    if a.json:
        print(json.dumps(res))
        return 0
    print(f"{'gt':>4} {'trk':>4} {'frames':>6} {'true':>7} {'speed':>7} {'err':>7} "
          f"{'L true':>7} {'L':>6} {'class true':>10} {'class':>10}")
    for v in res["vehicles"]:
        if v["track_id"] is None:
            print(f"{v['gt_id']:>4} {'-':>4}  (not tracked)  {v['class_true']:>39}")
            continue
        print(f"{v['gt_id']:>4} {v['track_id']:>4} {v['frames']:>6} {v['speed_true_kmh']:>7.1f} "
              f"{v['speed_kmh']:>7.1f} {v['speed_error_kmh']:>7.1f} {v['length_true_m']:>7.2f} "
              f"{v['length_m']:>6.2f} {v['class_true']:>10} {v['class']:>10}")
    s = {k: v for k, v in res.items() if k != "vehicles"}
    print(json.dumps(s, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
