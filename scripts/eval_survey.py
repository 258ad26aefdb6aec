"""Turning movements and line speeds of a run against a synthetic scene's ground truth.

    # the regions of a scene: gates across a junction's approaches, or count lines across
    # a mast scene's road, derived from world.csv and calibration.toml, as a config
    .venv/bin/python scripts/eval_survey.py regions SYNTH_DIR gates [--in-view] > gates.toml
    .venv/bin/python scripts/eval_survey.py regions SYNTH_DIR lines > lines.toml
    vtrack track SYNTH_DIR/video.avi --config gates.toml --out RUN_DIR [--calibration ...]
    .venv/bin/python scripts/eval_survey.py movements SYNTH_DIR RUN_DIR [--in-view] [--json]
    .venv/bin/python scripts/eval_survey.py speeds SYNTH_DIR RUN_DIR [--json]
    # the tracker's own ceiling: fed the true boxes (clean) instead of the detector's
    .venv/bin/python scripts/eval_survey.py truth-movements SYNTH_DIR
        [--source appearance|motion] [--config CFG.toml] [--in-view] [--json]

Regions (world.csv: `frame,id,X_m,Y_m,speed_kmh,...`, the vehicles' footprint centres on the
road; calibration.toml: the scene's exact homography). `gates`: the two roads cross at the
junction's centre (the world origin); their directions come from the vehicles seen beyond
ARM_MIN_M (k-means of the unit vectors, k = 4, started on the axes; a road's axis joins two
opposite clusters). Each of the four approaches gets a gate across it (half-length: the 97th
percentile of the road's vehicles' lateral offsets plus GATE_MARGIN_M) at the nearest
distance beyond the crossing road's gate half-length plus ARM_CLEAR_M whose middle is inside
the image and whose ends are in front of the camera (an approach with none within 40 m has
no gate); named by compass direction (north = world +Y). With `--in-view` a gate is cut to
the picture less EDGE_MARGIN of its sides, where a user can draw it, and taken only where at
least MIN_GATE_SHARE of it is left (else the next distance). `lines`: two count lines across
the road (its direction: the principal axis of the positions) where the road's middle is at
LINE_HEIGHTS of the image height (where a user would put them: in the near half of the view,
not at the horizon), spanning the lateral offsets plus GATE_MARGIN_M.

Truth (the same regions as the run used, read from RUN_DIR/summary.json, so the comparison
is of tracking, not of geometry): the true vehicles' box centres (gt.csv) in frame order
through the very rules `vtrack track` applies to its tracks (vtrack.analytics.gates
GateCounter for movements, lines.LineCounter for crossings); with `--in-view` only the rows
at least MIN_VISIBILITY visible, so a movement made out of sight is not counted.
`movements`: true and counted (movements.csv summed over bins and classes) per ordered pair
of gates. `speeds`: each true crossing's speed is world.csv's speed_kmh of that vehicle in
the frame of its crossing; per (bin, line, direction), the true 85th percentile (numpy's
linear interpolation, as speeds.csv) against speeds.csv's p85_kmh of class all; frame n is
at (n - 1) / fps s.

`truth-movements` takes the detector out: vtrack's tracker (default [tracker], or
--config's) is fed the visible true boxes (vtrack.evaluation.oracle, clean) as an
appearance detector's whole boxes (`--source appearance`, the default) or as motion blobs,
and its rows go through the scene's gates by the same rule; the movements it counts are the
tracker's own ceiling.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import tomllib
from collections import defaultdict
from pathlib import Path

import numpy as np

from vtrack.analytics.calibration import parse_calibration
from vtrack.analytics.gates import GateCounter
from vtrack.analytics.lines import LineCounter
from vtrack.evaluation.mot import MIN_VISIBILITY, read_mot

ARM_MIN_M = 12.0        # world points farther than this from the centre show the approaches
ARM_CLEAR_M = 4.0       # a gate lies this far beyond the other gates' half-lengths
GATE_MARGIN_M = 1.5     # beyond the outermost vehicle positions across the road
EDGE_MARGIN = 0.05      # a gate keeps this share of the picture's width/height off its edges
MIN_GATE_SHARE = 0.5    # ... and at least this share of its length across the road
COMPASS = ("east", "north", "west", "south")
LINE_HEIGHTS = (0.5, 0.75)   # mast count lines cross the road's middle at these image heights


def _world(path: Path) -> np.ndarray:
    """world.csv as (frame, id, X, Y, speed_kmh) rows."""
    with open(path, newline="") as fh:
        rows = [[float(r[k]) for k in ("frame", "id", "X_m", "Y_m", "speed_kmh")]
                for r in csv.DictReader(fh)]
    return np.array(rows).reshape(-1, 5)


def _calibration(synth: Path):
    with open(synth / "calibration.toml", "rb") as fh:
        return parse_calibration(tomllib.load(fh), str(synth / "calibration.toml"))


def _in_view(cal, pts: np.ndarray, width: int, height: int) -> tuple[np.ndarray, bool]:
    """Pixels of road points and whether all are in front of the camera (they map back onto
    the road side of the horizon) and the first is inside the image."""
    px = cal.to_image(pts)
    ok = bool(np.all(np.isfinite(px)) and np.all(np.isfinite(cal.to_world(px))))
    return px, ok and 0 <= px[0, 0] < width and 0 <= px[0, 1] < height


def gate_regions(world: np.ndarray, cal, width: int, height: int, in_view: bool = False
                 ) -> list[dict]:
    """[[gates]] tables (px) across the approaches of a junction (module docstring);
    `in_view`: each cut to the picture (`_inside`), where a user can draw it."""
    xy = world[:, 2:4]
    far = xy[np.hypot(*xy.T) > ARM_MIN_M]
    u = far / np.hypot(*far.T)[:, None]
    centres = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    for _ in range(20):
        label = np.argmax(u @ centres.T, axis=1)
        for k in range(4):
            if np.any(label == k):
                m = u[label == k].mean(axis=0)
                centres[k] = m / np.hypot(*m)
    roads = []                                     # (axis, normal, half-length of a gate)
    for k in (0, 1):
        a = centres[k] - centres[k + 2]
        axis = a / np.hypot(*a)
        n = np.array([-axis[1], axis[0]])
        mine = far[(label == k) | (label == k + 2)]
        roads.append((axis, n, float(np.percentile(np.abs(mine @ n), 97)) + GATE_MARGIN_M))
    gates = []
    for k in range(4):
        axis, n, half = roads[k % 2]
        d = axis if k < 2 else -axis
        start = roads[1 - k % 2][2] + ARM_CLEAR_M      # beyond the crossing road
        angle = math.degrees(math.atan2(d[1], d[0]))
        name = COMPASS[int(round(angle / 90.0)) % 4]
        for dist in np.arange(start, start + 40.0, 0.5):
            ends = np.array([dist * d, dist * d - half * n, dist * d + half * n])
            px, ok = _in_view(cal, ends, width, height)
            if not ok:
                continue
            line = _inside(px[1:], width, height) if in_view else px[1:]
            if line is not None:
                gates.append({"name": name, "line": [[round(float(x), 1), round(float(y), 1)]
                                                     for x, y in line]})
                break
    return gates


def _inside(line: np.ndarray, width: int, height: int) -> np.ndarray | None:
    """The part of a gate (2, 2) px inside the picture inset by EDGE_MARGIN of its sides (a
    user draws a gate where the vehicles crossing it are in view), if at least
    MIN_GATE_SHARE of it."""
    mx, my = EDGE_MARGIN * width, EDGE_MARGIN * height
    lo, hi = np.array([mx, my]), np.array([width - mx, height - my])
    a, b = line
    t0, t1 = 0.0, 1.0                        # Liang-Barsky: clip a + t (b - a) to [lo, hi]
    for p, q in ((-(b - a), a - lo), (b - a, hi - a)):
        for k in range(2):
            if p[k] == 0:
                if q[k] < 0:
                    return None
            elif p[k] < 0:
                t0 = max(t0, q[k] / p[k])
            else:
                t1 = min(t1, q[k] / p[k])
    if t1 - t0 < MIN_GATE_SHARE:
        return None
    return np.array([a + t0 * (b - a), a + t1 * (b - a)])


def line_regions(world: np.ndarray, cal, width: int, height: int) -> list[dict]:
    """count_lines tables (px) across a straight road (module docstring)."""
    xy = world[:, 2:4]
    c = xy.mean(axis=0)
    _, _, vt = np.linalg.svd(xy - c, full_matrices=False)
    d, n = vt[0], vt[1]
    along, across = (xy - c) @ d, (xy - c) @ n
    lo, hi = np.min(across) - GATE_MARGIN_M, np.max(across) + GATE_MARGIN_M
    lines = []
    grid = np.linspace(along.min(), along.max(), 400)
    mid_y = cal.to_image(c + grid[:, None] * d + 0.5 * (lo + hi) * n)[:, 1]
    for k, share in enumerate(LINE_HEIGHTS):
        s = float(grid[np.nanargmin(np.abs(mid_y - share * height))])
        ends = c + np.array([s * d + 0.5 * (lo + hi) * n, s * d + lo * n, s * d + hi * n])
        px, _ = _in_view(cal, ends, width, height)
        lines.append({"name": f"L{k + 1}", "points": [[round(float(x), 1), round(float(y), 1)]
                                                      for x, y in px[1:]]})
    return lines


def regions_toml(synth: Path, kind: str, width: int = 640, height: int = 360,
                 in_view: bool = False) -> str:
    """The config text with the scene's gates (`in_view`: cut to the picture) or count
    lines."""
    cal = _calibration(synth)
    if cal.frame_size is not None:
        width, height = cal.frame_size
    world = _world(synth / "world.csv")
    if kind == "gates":
        return "".join(f'[[gates]]\nname = "{g["name"]}"\nline = {g["line"]}\n\n'
                       for g in gate_regions(world, cal, width, height, in_view))
    return "count_lines = [\n" + "".join(
        f'  {{name = "{l["name"]}", points = {l["points"]}}},\n'
        for l in line_regions(world, cal, width, height)) + "]\n"


def _paths(gt: np.ndarray):
    """(id, frame, box centre) of MOT rows, each id's in frame order."""
    rows = gt[np.lexsort((gt[:, 0], gt[:, 1]))]
    for r in rows:
        yield int(r[1]), int(r[0]), r[2:4] + r[4:6] / 2


def _summary(run: Path) -> dict:
    return json.loads((run / "summary.json").read_text())


def _csv(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _gate_passes(rows: np.ndarray, gates: list[dict], fps: float
                 ) -> tuple[dict[tuple[str, str], int], dict[str, int]]:
    """Movements per ordered pair and passes per gate of MOT rows' box-centre paths through
    the gates, by the rule `vtrack track` applies (GateCounter)."""
    counter = GateCounter([g["name"] for g in gates],
                          [np.array(g.get("line", g.get("polygon"))) for g in gates],
                          ["line" in g for g in gates])
    passes = dict.fromkeys(counter.names, 0)
    last = None

    def end(tid: int) -> None:
        for g in counter._passes.get(tid, {}):
            passes[counter.names[g]] += 1
        counter.end_track(tid)

    for tid, frame, centre in _paths(rows):
        if last is not None and tid != last:
            end(last)
        counter.add(tid, frame, (frame - 1) / fps, centre)
        last = tid
    if last is not None:
        end(last)
    return {(m["from"], m["to"]): m["count"] for m in counter.summary()}, passes


def _truth(synth: Path, in_view: bool) -> np.ndarray:
    """gt.csv's rows; `in_view`: only those at least MIN_VISIBILITY visible (the rows the
    oracle and the scoring use: a movement made out of sight is not one a camera sees)."""
    gt = read_mot(synth / "gt.csv", max_cols=11)
    return gt[gt[:, 10] >= MIN_VISIBILITY] if in_view else gt


def evaluate_movements(synth: Path, run: Path, in_view: bool = False) -> dict:
    """Counted / true per ordered pair of the run's gates; and per gate the tracks and the
    true vehicles that passed it (a movement needs one track through two gates); `in_view`:
    the true vehicles' rows in view only (`_truth`)."""
    s = _summary(run)
    gates, fps = s["gates"], s["fps_video"] or 25.0
    true, true_passes = _gate_passes(_truth(synth, in_view), gates, fps)
    _, passes = _gate_passes(read_mot(run / "tracks.csv"), gates, fps)
    counted: dict[tuple[str, str], int] = defaultdict(int)
    for r in _csv(run / "movements.csv"):
        counted[(r["from"], r["to"])] += int(r["count"])
    return _movement_table(true, dict(counted), true_passes, passes,
                           [g["name"] for g in gates])


def _movement_table(true: dict, counted: dict, true_passes: dict, passes: dict,
                    gates: list[str]) -> dict:
    """Counted / true per ordered pair of gates (those that occurred or were counted), with
    `matched` (per pair the smaller of the two, summed: movements counted that happened)."""
    per = [{"from": a, "to": b, "true": true.get((a, b), 0), "counted": counted.get((a, b), 0)}
           for a, b in sorted(set(true) | set(counted))
           if true.get((a, b), 0) or counted.get((a, b), 0)]
    t, c = sum(p["true"] for p in per), sum(p["counted"] for p in per)
    return {"gates": gates, "movements": per, "true": t, "counted": c,
            "matched": sum(min(p["true"], p["counted"]) for p in per),
            "abs_error": sum(abs(p["counted"] - p["true"]) for p in per),
            "passes": {g: {"tracked": passes[g], "true": true_passes[g]} for g in passes}}


def evaluate_truth_movements(synth: Path, source: str = "appearance",
                             config_path: str | None = None, in_view: bool = False) -> dict:
    """Movements counted from vtrack's tracker fed the true boxes (module docstring);
    `in_view`: gates cut to the picture and the true vehicles' rows in view only."""
    from vtrack.app import config
    from vtrack.evaluation.oracle import oracle_detections, tracked_rows
    from vtrack.tracking.tracker import Tracker

    cal = _calibration(synth)
    width, height = cal.frame_size if cal.frame_size is not None else (640, 360)
    gates = gate_regions(_world(synth / "world.csv"), cal, width, height, in_view)
    fps = 25.0   # `vtrack synth`'s default
    gt = read_mot(synth / "gt.csv", max_cols=11)
    true, true_passes = _gate_passes(_truth(synth, in_view), gates, fps)
    tracker = Tracker(config.load(config_path).tracker, width, height, fps)
    rows = tracked_rows(tracker, oracle_detections(gt), int(gt[:, 0].max()), fps,
                        whole=source == "appearance", video=synth / "video.avi")
    counted, passes = _gate_passes(rows, gates, fps)
    return _movement_table(true, counted, true_passes, passes, [g["name"] for g in gates])


def evaluate_speeds(synth: Path, run: Path) -> dict:
    """Per (bin, line, direction): true and measured p85 (module docstring)."""
    s = _summary(run)
    fps, bin_s = s["fps_video"] or 25.0, s["bin_seconds"]
    labels = [c.get("name", str(k)) for k, c in enumerate(s["counts"])]
    counter = LineCounter([c["line"] for c in s["counts"]])
    world = _world(synth / "world.csv")
    speed = {(int(f), int(i)): v for f, i, _, _, v in world}
    true: dict[tuple[int, str, str], list[float]] = defaultdict(list)
    for tid, frame, centre in _paths(read_mot(synth / "gt.csv", max_cols=11)):
        for c in counter.add(tid, frame, (frame - 1) / fps, centre):
            v = speed.get((frame, tid))
            if v is not None:
                true[(int(c.time // bin_s), labels[c.line], c.direction)].append(v)
    measured = {(int(round(float(r["bin_start_s"]) / bin_s)), r["line"], r["direction"]): r
                for r in _csv(run / "speeds.csv") if r["class"] == "all"}
    per = []
    for key in sorted(set(true) | {k for k, r in measured.items() if int(r["count"])}):
        t, m = true.get(key, []), measured.get(key)
        p85_true = float(np.percentile(t, 85)) if t else math.nan
        p85 = float(m["p85_kmh"]) if m and m["p85_kmh"] else math.nan
        per.append({"bin_start_s": key[0] * bin_s, "line": key[1], "direction": key[2],
                    "true_n": len(t), "n": int(m["count"]) if m else 0,
                    "p85_true_kmh": round(p85_true, 2), "p85_kmh": round(p85, 2),
                    "p85_error_kmh": round(p85 - p85_true, 2)})
    e = np.array([p["p85_error_kmh"] for p in per], dtype=float)
    e = e[np.isfinite(e)]
    return {"bins": per, "compared": int(len(e)),
            "p85_mae_kmh": round(float(np.mean(np.abs(e))), 2) if len(e) else None,
            "p85_bias_kmh": round(float(np.mean(e)), 2) if len(e) else None,
            "p85_abs_max_kmh": round(float(np.max(np.abs(e))), 2) if len(e) else None}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("regions")
    r.add_argument("synth", type=Path)
    r.add_argument("kind", choices=("gates", "lines"))
    in_view = {"action": "store_true", "help": "gates cut to the picture (where a user can "
               "draw them) and the true vehicles' rows in view only"}
    r.add_argument("--in-view", **in_view)
    for name in ("movements", "speeds"):
        q = sub.add_parser(name)
        q.add_argument("synth", type=Path)
        q.add_argument("run", type=Path)
        q.add_argument("--json", action="store_true")
        if name == "movements":
            q.add_argument("--in-view", **in_view)
    q = sub.add_parser("truth-movements")
    q.add_argument("synth", type=Path)
    q.add_argument("--source", choices=("appearance", "motion"), default="appearance")
    q.add_argument("--config")
    q.add_argument("--in-view", **in_view)
    q.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    if a.cmd == "regions":
        print(regions_toml(a.synth, a.kind, in_view=a.in_view), end="")
        return 0
    if a.cmd == "truth-movements":
        res = evaluate_truth_movements(a.synth, a.source, a.config, a.in_view)
    elif a.cmd == "movements":
        res = evaluate_movements(a.synth, a.run, a.in_view)
    else:
        res = evaluate_speeds(a.synth, a.run)
    if a.json:
        print(json.dumps(res))
    elif a.cmd in ("movements", "truth-movements"):
        for m in res["movements"]:
            print(f"{m['from']:>6} -> {m['to']:<6} counted {m['counted']:>3} / true "
                  f"{m['true']:>3}")
        print(f"total counted {res['counted']} / true {res['true']}, matched "
              f"{res['matched']}, sum of |error| {res['abs_error']}")
        print("gate passes, tracks / true vehicles: " + ", ".join(
            f"{g} {p['tracked']}/{p['true']}" for g, p in res["passes"].items()))
    else:
        for b in res["bins"]:
            print(f"bin {b['bin_start_s']:>5g} s {b['line']:>4} {b['direction']:<8} n "
                  f"{b['n']:>3} / {b['true_n']:>3}  p85 {b['p85_kmh']:>6.1f} true "
                  f"{b['p85_true_kmh']:>6.1f} error {b['p85_error_kmh']:>6.1f} km/h")
        print({k: v for k, v in res.items() if k != "bins"})
    return 0


if __name__ == "__main__":
    sys.exit(main())
