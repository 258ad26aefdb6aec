#!/usr/bin/env python3
"""The scene suite: the instrument every tracker change is judged on.

Runs, with the DEFAULT configuration (or --config), every synthetic scene preset of
`vtrack synth` with several seeds plus every real clip of ../shared/videos/handcounts.json
with its counting line, through `vtrack track`; then runs two peers, SORT and ByteTrack from
the `trackers` package (Roboflow), on exactly the detections vtrack's detector produced
for that clip (`vtrack track --save-detections`), and the peer a user would pick instead of
vtrack, the appearance model's boxes on every frame tracked by ByteTrack
("yolox+bytetrack"), all counted with the same line rule. Prints one
table: per synthetic clip MOTA, IDF1, HOTA, ID switches, FP, FN per tracker and the recall of
the raw detections (the detector's ceiling: a loss above it is the tracker's, below it the
detector's); per synthetic clip the counts on two lines (y = 0.6 H and x = 0.5 W) beside the
true counts, which the same line rule gives on the ground truth's boxes; per real clip and
line the counts beside the hand range; the mean and the worst per column, and MOTChallenge's
combined scores over the synthetic clips (their counts pooled). A second table scores the
same rows with the vehicles that have not yet moved (parked or queued from the first frame:
background to any motion detector) as ignore regions, beside the share of the ground truth
left: the ceiling of a background-subtraction tracker's MOTA on the clip.

    .venv/bin/python scripts/eval_suite.py                 # the whole suite, 2 workers
    .venv/bin/python scripts/eval_suite.py --json suite.json
    .venv/bin/python scripts/eval_suite.py --quick         # one short clip per preset, 2 real
    .venv/bin/python scripts/eval_suite.py --without shadows --no-real   # what a nuisance costs

`--without` renders the perspective clips with those nuisances of `vtrack synth` taken out
and everything else the same. Each nuisance draws from its own random stream, so the same
vehicles drive the same paths, except without `mix`, `parked` or `inview`, which are inputs
of the traffic draw: the suite's score without a phenomenon is what handling it perfectly
would be worth, for vtrack and for the peers.

Rendered synthetic clips are cached (keyed by the simulator's source and the options) under
--cache, so re-running after a tracker change only tracks. Peers need the `peer` extra
(scripts/setup_env.sh installs it); --no-peers skips them.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from vtrack.sim.nuisance import NUISANCES

ROOT = Path(__file__).resolve().parents[1]
VIDEOS = ROOT.parent / "shared" / "videos"
SCENES = ("overhead", "mast", "side", "junction")
PEERS = ("sort", "bytetrack")
# the peer a user would pick instead of vtrack: the appearance model's boxes on every frame
# (`vtrack track` with kind = "appearance", boxes down to a score of 0.1 for ByteTrack's
# second stage) tracked by ByteTrack, its thresholds set to YOLOX-Nano's scores (the
# package's defaults, 0.7 to start a track and 0.6 for a first-stage box, suit a stronger
# detector: with them it starts almost no track on these scenes)
APPEARANCE_PEER = "yolox+bytetrack"
APPEARANCE_CONFIG = '[detector]\nkind = "appearance"\nappearance_score = 0.1\n'
APPEARANCE_BYTETRACK = {"track_activation_threshold": 0.3, "high_conf_det_threshold": 0.3}
METRICS = ("mota", "idf1", "hota", "id_switches", "false_positives", "misses")
MOVED_METRICS = ("mota", "idf1", "hota")
HIGHER_IS_BETTER = {"mota", "idf1", "hota"}


@dataclass(frozen=True)
class SynthClip:
    scene: str
    seed: int
    frames: int = 300
    width: int = 640
    height: int = 360
    without: tuple[str, ...] = ()   # nuisances taken out (perspective scenes)

    @property
    def name(self) -> str:
        size = "" if (self.width, self.height) == (640, 360) else f"@{self.width}x{self.height}"
        return f"{self.scene}-{self.seed}{size}"


@dataclass(frozen=True)
class RealClip:
    file: str
    lines: tuple[tuple[float, tuple[int, int], tuple[int, int]], ...]  # y_frac, fwd, bwd

    @property
    def name(self) -> str:
        return Path(self.file).stem


@dataclass
class Result:
    clip: str
    kind: str                                  # "synthetic" | "real"
    seconds: float = 0.0
    frames: int = 0
    scores: dict[str, dict] = field(default_factory=dict)   # tracker -> metrics
    counts: dict[str, list] = field(default_factory=dict)   # tracker -> [[fwd, bwd], ...]
    hand: list = field(default_factory=list)   # [[line, [lo, hi], [lo, hi]], ...]: the hand
    #                                            range (real) or the true count (synthetic)
    detector: dict = field(default_factory=dict)            # recall, precision (synthetic)
    hidden: list = field(default_factory=list)  # [[fwd, bwd], ...]: true crossings made out
    #                                             of sight (synthetic; oracle.hidden_crossings)
    files: dict[str, str] = field(default_factory=dict)     # "gt" and tracker -> MOT file
    error: str = ""


# ----------------------------------------------------------------------------- clips

def synthetic_clips(scenes: list[str], seeds: list[int], frames: int, large: bool,
                    without: tuple[str, ...] = ()) -> list[SynthClip]:
    clips = [SynthClip(s, seed, frames, without=without) for s in scenes for seed in seeds]
    if large and scenes:
        big = "mast" if "mast" in scenes else scenes[0]
        clips.append(SynthClip(big, seeds[0] + 100, frames, 1280, 720, without))
    return clips


def real_clips() -> list[RealClip]:
    path = VIDEOS / "handcounts.json"
    if not path.exists():
        return []
    by_file: dict[str, list] = {}
    for c in json.loads(path.read_text())["clips"]:
        by_file.setdefault(c["file"], []).append(
            (c["y_fraction"], tuple(c["forward"]), tuple(c["backward"])))
    return [RealClip(f, tuple(lines)) for f, lines in by_file.items()
            if (VIDEOS / f).exists()]


# ----------------------------------------------------------------------------- running

def _vtrack(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "vtrack", *args], capture_output=True,
                          text=True, env=env, check=False)


def _sim_digest() -> str:
    h = hashlib.sha256()
    for p in sorted((ROOT / "vtrack" / "sim").rglob("*.py")):
        h.update(p.read_bytes())
    return h.hexdigest()[:12]


def render(clip: SynthClip, cache: Path) -> Path:
    """Render (or reuse) a synthetic clip; returns its folder."""
    key = hashlib.sha256(f"{_sim_digest()}{asdict(clip)}".encode()).hexdigest()[:12]
    out = cache / f"{clip.name}-{key}"
    if (out / "gt.csv").exists() and (out / "video.avi").exists():
        return out
    args = ["synth", str(out), "--seed", str(clip.seed), "--frames", str(clip.frames),
            "--width", str(clip.width), "--height", str(clip.height)]
    if clip.scene != "overhead":
        args += ["--scene", clip.scene]
        if clip.without:
            kept = [n for n in NUISANCES if n not in clip.without]
            args += ["--nuisance", ",".join(kept) or "none"]
    res = _vtrack(*args)
    if res.returncode != 0:
        raise RuntimeError(f"synth {clip.name}: {res.stderr.strip()}")
    return out


def track(video: Path, out: Path, lines: list[list[float]], config: str | None) -> dict:
    args = ["track", str(video), "--out", str(out), "--quiet", "--save-detections"]
    for line in lines:
        args += ["--count-line", ",".join(f"{v:g}" for v in line)]
    if config:
        args += ["--config", config]
    res = _vtrack(*args)
    if res.returncode != 0:
        raise RuntimeError(f"track {video}: {res.stderr.strip()}")
    return json.loads((out / "summary.json").read_text())


def read_detections(path: Path) -> np.ndarray:
    """The rows (D, 10) of a detections.csv (`vtrack track --save-detections`)."""
    return (np.loadtxt(path, delimiter=",", ndmin=2) if path.stat().st_size
            else np.zeros((0, 10)))


def peer_rows(name: str, dets: np.ndarray, frames: int, fps: float, **options: float
              ) -> np.ndarray:
    """Track detections (rows of MOT columns: frame, -, x, y, w, h, conf) with a peer of
    the `trackers` package (`options`: its tracker's keyword arguments); its rows (frame,
    id, x, y, w, h), sorted by frame then id."""
    import supervision as sv
    from trackers import ByteTrackTracker, SORTTracker

    tracker = (SORTTracker if name == "sort" else ByteTrackTracker)(frame_rate=fps, **options)
    by_frame = {int(f): dets[dets[:, 0] == f] for f in np.unique(dets[:, 0])}
    rows = []
    for n in range(1, frames + 1):
        d = by_frame.get(n, np.zeros((0, 10)))
        xyxy = np.column_stack([d[:, 2], d[:, 3], d[:, 2] + d[:, 4], d[:, 3] + d[:, 5]])
        result = tracker.update(sv.Detections(xyxy=xyxy.reshape(-1, 4).astype(float),
                                              confidence=d[:, 6].astype(float)))
        for (x0, y0, x1, y1), tid in zip(result.xyxy, result.tracker_id, strict=True):
            if tid is not None and tid >= 0 and x1 > x0 and y1 > y0:
                rows.append((n, int(tid) + 1, x0, y0, x1 - x0, y1 - y0))
    rows.sort(key=lambda r: (r[0], r[1]))
    return np.array(rows, dtype=float).reshape(-1, 6)


def run_peer(name: str, detections: Path, fps: float, frames: int, out: Path,
             **options: float) -> Path:
    """Track vtrack's detections with a peer of the `trackers` package; writes MOT rows."""
    path = out / f"tracks_{name}.csv"
    with path.open("w") as f:
        for n, tid, x, y, w, h in peer_rows(name, read_detections(detections), frames, fps,
                                            **options):
            f.write(f"{int(n)},{int(tid)},{x:.2f},{y:.2f},{w:.2f},{h:.2f},1,-1,-1,-1\n")
    return path


def appearance_peer(video: Path, out: Path, lines: list[list[float]], summary: dict) -> Path:
    """APPEARANCE_PEER's tracks of `video`: the appearance model's boxes of every frame
    (`vtrack track` with APPEARANCE_CONFIG) tracked by ByteTrack; writes MOT rows."""
    out.mkdir(parents=True, exist_ok=True)
    config = out / "appearance.toml"
    config.write_text(APPEARANCE_CONFIG)
    track(video, out, lines, str(config))
    path = run_peer("bytetrack", out / "detections.csv", summary["fps_video"],
                    summary["frames"], out, **APPEARANCE_BYTETRACK)
    return path.rename(out.parent / f"tracks_{APPEARANCE_PEER}.csv")


def count(tracks: Path, lines: list[list[float]]) -> list[list[int]]:
    """[forward, backward] per line of a MOT file's rows by the rule of `vtrack track`."""
    from vtrack.analytics.lines import count_rows

    rows = np.loadtxt(tracks, delimiter=",", ndmin=2) if tracks.stat().st_size else \
        np.zeros((0, 10))
    return count_rows(rows, lines)


def run_clip(clip: SynthClip | RealClip, work: Path, cache: Path, config: str | None,
             peers: bool) -> Result:
    from vtrack.evaluation.detector_misses import miss_table
    from vtrack.evaluation.false_positives import false_positive_counts, false_positive_shapes
    from vtrack.evaluation.mot import detection_scores, evaluate_arrays, read_mot
    from vtrack.evaluation.oracle import (hidden_crossings, moved_share, moved_visible,
                                          unmoved_ignored)

    t0 = time.perf_counter()
    synthetic = isinstance(clip, SynthClip)
    res = Result(clip.name, "synthetic" if synthetic else "real")
    try:
        out = work / clip.name
        if synthetic:
            src = render(clip, cache)
            video = src / "video.avi"
            from vtrack.sim.clip import scored_count_lines

            named = scored_count_lines(clip.width, clip.height)
            lines = [line for _, line in named]
        else:
            video = VIDEOS / clip.file
            import cv2

            cap = cv2.VideoCapture(str(video))
            w, h = cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)
            cap.release()
            lines = [[0.0, y * h, w, y * h] for y, _, _ in clip.lines]
            res.hand = [[f"{y:.2f} H", list(f), list(b)] for y, f, b in clip.lines]
        summary = track(video, out, lines, config)
        res.frames = summary["frames"]
        outputs = {"vtrack": out / "tracks.csv"}
        if peers:
            for name in PEERS:
                outputs[name] = run_peer(name, out / "detections.csv", summary["fps_video"],
                                         summary["frames"], out)
            outputs[APPEARANCE_PEER] = appearance_peer(video, out / "appearance", lines,
                                                       summary)
        if synthetic:
            gt, dets = read_mot(src / "gt.csv"), read_detections(out / "detections.csv")
            res.detector = detection_scores(gt, dets) | {"misses": miss_table(gt, dets)}
            truth = count(src / "gt.csv", lines)
            res.hand = [[label, [f, f], [b, b]] for (label, _), (f, b) in zip(named, truth)]
            res.hidden = hidden_crossings(gt, lines)
            moved_gt = unmoved_ignored(gt)
            res.detector["moved_share"] = moved_share(gt, moved_gt)
            res.detector["recall_moved"] = detection_scores(moved_visible(gt), dets)["recall"]
        for name, path in outputs.items():
            if synthetic:
                res.files |= {"gt": str(src / "gt.csv"), name: str(path)}
                rows = read_mot(path)
                s = evaluate_arrays(gt, rows)
                res.scores[name] = {k: s[k] for k in METRICS}
                res.scores[name]["fp_causes"] = false_positive_counts(gt, dets, rows)
                res.scores[name]["fp_shapes"] = false_positive_shapes(gt, rows)
                moved = evaluate_arrays(moved_gt, rows)
                res.scores[name]["moved"] = {k: moved[k] for k in MOVED_METRICS}
            res.counts[name] = count(path, lines)
    except Exception as exc:  # noqa: BLE001 - a failing clip is reported, the suite goes on
        res.error = f"{type(exc).__name__}: {exc}"
    res.seconds = time.perf_counter() - t0
    return res


# ----------------------------------------------------------------------------- report

def count_error(c: int, lo: int, hi: int) -> int:
    """Signed distance of a count from its hand range (0 inside)."""
    return c - hi if c > hi else (c - lo if c < lo else 0)


def count_summary(results: list[Result], tracker: str, counts: str, count: str) -> dict:
    """How a tracker's counts compare with the hand ranges (or true counts) of `results`:
    {counts}_in_range, {counts}_within_1, {counts}_total, {count}_abs_error_sum,
    {count}_worst_relative (error / the range's top) and, for synthetic clips where the
    truth is exact, {count}_relative_error (sum of |errors| / sum of true counts)."""
    errs = []
    for r in results:
        for (_, fwd, bwd), got in zip(r.hand, r.counts.get(tracker, []), strict=False):
            for (lo, hi), c in zip((fwd, bwd), got, strict=True):
                errs.append((count_error(c, lo, hi), hi))
    if not errs:
        return {}
    e = np.array([abs(a) for a, _ in errs])
    return {f"{counts}_in_range": int(np.sum(e == 0)),
            f"{counts}_within_1": int(np.sum(e <= 1)),
            f"{counts}_total": len(errs),
            f"{count}_abs_error_sum": int(e.sum()),
            f"{count}_worst_relative": float(max(abs(a) / max(hi, 1) for a, hi in errs)),
            f"{count}_relative_error": float(e.sum() / max(sum(hi for _, hi in errs), 1))}


def combined_scores(results: list[Result], tracker: str) -> dict:
    """MOTChallenge's combined scores of a tracker over the synthetic clips it ran on
    (`mot.evaluate_combined`: the clips' counts pooled, so a clip weighs by its boxes)."""
    from vtrack.evaluation.mot import evaluate_combined, read_mot

    pairs = [(read_mot(r.files["gt"]), read_mot(r.files[tracker])) for r in results
             if tracker in r.files]
    if not pairs:
        return {}
    comb = evaluate_combined(pairs)
    return {m: comb[m] for m in METRICS}


def summarise(results: list[Result], trackers: list[str]) -> dict:
    out: dict[str, dict] = {}
    synth = [r for r in results if r.kind == "synthetic" and not r.error]
    real = [r for r in results if r.kind == "real" and not r.error]
    for t in trackers:
        s: dict = {}
        for m in METRICS:
            vals = [r.scores[t][m] for r in synth if t in r.scores]
            if vals:
                s[f"{m}_mean"] = float(np.mean(vals))
                s[f"{m}_worst"] = float(min(vals) if m in HIGHER_IS_BETTER else max(vals))
        for m in MOVED_METRICS:
            vals = [r.scores[t]["moved"][m] for r in synth if "moved" in r.scores.get(t, {})]
            if vals:
                s.setdefault("moved", {})[f"{m}_mean"] = float(np.mean(vals))
                s["moved"][f"{m}_worst"] = float(min(vals))
        combined = combined_scores(synth, t)
        if combined:
            s["combined"] = combined
        s.update(count_summary(real, t, "counts", "count"))
        s.update(count_summary(synth, t, "synth_counts", "synth_count"))
        out[t] = s
    hidden = [d for r in synth for line in r.hidden for d in line]
    if hidden:
        out["synth_counts_ceiling"] = {
            "line_directions": len(hidden),
            "with_hidden_crossing": int(np.count_nonzero(hidden)),
            "hidden_crossings": int(np.sum(hidden))}
    recall = [r.detector["recall"] for r in synth if r.detector]
    if recall:
        out["detector"] = {"recall_mean": float(np.mean(recall)),
                           "recall_worst": float(min(recall))}
        moved = [r.detector["moved_share"] for r in synth if "moved_share" in r.detector]
        if moved:
            out["detector"]["moved_share_mean"] = float(np.mean(moved))
        seen = [r.detector["recall_moved"] for r in synth if "recall_moved" in r.detector]
        if seen:
            out["detector"]["recall_moved_mean"] = float(np.mean(seen))
            out["detector"]["recall_moved_worst"] = float(min(seen))
    return out


def print_table(results: list[Result], trackers: list[str], summary: dict) -> None:
    synth = [r for r in results if r.kind == "synthetic"]
    if synth:
        print(f"{'synthetic clip':<22}{'tracker':<16}{'MOTA':>7}{'IDF1':>7}{'HOTA':>7}"
              f"{'IDsw':>6}{'FP':>6}{'FN':>6}{'det.recall':>12}")
        for r in synth:
            if r.error:
                print(f"{r.clip:<22}error: {r.error}")
                continue
            for t in trackers:
                s = r.scores.get(t)
                if s:
                    first = t == trackers[0]
                    ceiling = f"{r.detector['recall']:12.3f}" if first and r.detector else ""
                    print(f"{r.clip if first else '':<22}{t:<16}{s['mota']:7.3f}"
                          f"{s['idf1']:7.3f}{s['hota']:7.3f}{s['id_switches']:6d}"
                          f"{s['false_positives']:6d}{s['misses']:6d}{ceiling}")
        for agg in ("mean", "worst", "combined"):
            for t in trackers:
                s = summary.get(t, {})
                if "mota_mean" not in s or (agg == "combined" and "combined" not in s):
                    continue
                v = ([s["combined"][m] for m in METRICS] if agg == "combined"
                     else [s[f"{m}_{agg}"] for m in METRICS])
                det = summary.get("detector", {})
                first = t == trackers[0]
                ceiling = (f"{det[f'recall_{agg}']:12.3f}"
                           if first and f"recall_{agg}" in det else "")
                print(f"{agg if first else '':<22}{t:<16}{v[0]:7.3f}{v[1]:7.3f}"
                      f"{v[2]:7.3f}{v[3]:6.0f}{v[4]:6.0f}{v[5]:6.0f}{ceiling}")
        print("det.recall: the share of the ground truth the raw detections match (IoU >= "
              "0.5, one to one),\nthe ceiling of a tracker's MOTA on them without coasting; "
              "combined: MOTChallenge's scores\nover all synthetic clips pooled (a clip "
              "weighs by its boxes; mean: each clip alike)")
        print()
        print_moved([r for r in synth if not r.error], trackers, summary)
        print_misses([r for r in synth if r.detector.get("misses")])
        print_false_positives([r for r in synth if not r.error], trackers)
    print_counts([r for r in synth if r.counts], trackers, summary, "synthetic clip",
                 "true", "synth_counts", "synth_count")
    print_counts([r for r in results if r.kind == "real"], trackers, summary, "real clip",
                 "hand", "counts", "count")


def print_moved(results: list[Result], trackers: list[str], summary: dict) -> None:
    """Per synthetic clip, the scores with each vehicle's rows before it first moves as
    ignore regions (what a motion detector can see; oracle.unmoved_ignored), and the share
    of the visible ground truth left scored: the ceiling of any background-subtraction
    tracker's MOTA on the full ground truth."""
    rows = [r for r in results if all("moved" in r.scores.get(t, {}) for t in trackers)]
    if not rows:
        return
    print(f"{'vehicles once moved':<22}{'moved':>7}{'det.rec':>8}"
          + "".join(f"{t + ' MOTA/IDF1/HOTA':>31}" for t in trackers))
    for r in rows:
        print(f"{r.clip:<22}{r.detector['moved_share']:7.3f}"
              f"{r.detector.get('recall_moved', float('nan')):8.3f}" + "".join(
            f"{'':>10}" + " / ".join(f"{r.scores[t]['moved'][m]:6.3f}" for m in MOVED_METRICS)
            for t in trackers))
    share = summary.get("detector", {}).get("moved_share_mean", float("nan"))
    seen = summary.get("detector", {}).get("recall_moved_mean", float("nan"))
    print(f"{'mean':<22}{share:7.3f}{seen:8.3f}" + "".join(
        f"{'':>10}" + " / ".join(f"{summary[t]['moved'][m + '_mean']:6.3f}"
                                 for m in MOVED_METRICS) for t in trackers))
    print("moved: the share of the visible ground truth whose vehicle has moved half a box "
          "scale from where\nit was first seen (the rest, parked or queued from the start, "
          "is background to MOG2): the ceiling\nof any motion detector's MOTA; the scores "
          "beside it take the rest as ignore regions; det.rec: the raw detections' recall "
          "on the\nvehicles once moved and at least 70 % visible (oracle.moved_visible)")
    print()


def print_misses(results: list[Result]) -> None:
    """Per synthetic clip, where the raw detections lose the visible ground truth
    (vtrack/evaluation/detector_misses.py): the share of it in each class, then the share
    of the boxes no detection covers among the far (side < 15 px), middle and near ones
    and among the standing (< 0.5 px per frame), slow and moving ones."""
    from vtrack.evaluation.detector_misses import CLASSES

    if not results:
        return
    table = results[0].detector["misses"]["none_by_side_speed"]
    bands = [f"{b}px" for b in table] + [f"{v}px/f" for v in next(iter(table.values()))]
    print(f"{'detector misses':<22}" + "".join(f"{c:>9}" for c in CLASSES)
          + "".join(f"{'none@' + b:>16}" for b in bands))
    total = {c: 0.0 for c in CLASSES}
    for r in results:
        m = r.detector["misses"]
        for c in CLASSES:
            total[c] += m["shares"][c] * m["rows"]
        table = m["none_by_side_speed"]
        cells = [list(band.values()) for band in table.values()]           # side x speed
        groups = cells + [list(col) for col in zip(*cells)]              # then speed bands
        none = []
        for group in groups:
            rows = sum(v[0] for v in group)
            share = sum(v[0] * v[1] for v in group) / max(rows, 1)
            none.append(f"{share:6.2f} of {rows:<5d}")
        print(f"{r.clip:<22}" + "".join(f"{m['shares'][c]:9.2f}" for c in CLASSES)
              + "".join(f"{x:>16}" for x in none))
    n = max(sum(r.detector["misses"]["rows"] for r in results), 1)
    print(f"{'all':<22}" + "".join(f"{total[c] / n:9.2f}" for c in CLASSES))
    print("a visible box no detection matches: none (< 30 % of it covered), merged (inside a "
          "blob > 1.6x its\narea), fragment (the best blob < 0.6x), offset; none@a-b: the "
          "share of the boxes of side a-b px\n(or moving a-b px per frame) that no "
          "detection covers")
    print()


def print_false_positives(results: list[Result], trackers: list[str]) -> None:
    """Per synthetic clip and tracker, its false positives by cause and by where the box lies
    on the ground truth (vtrack/evaluation/false_positives.py), and the sums over the
    clips."""
    from vtrack.evaluation.false_positives import CLASSES, SHAPES

    if not results:
        return
    heads = ("coasted", "false det.", "box off det.", "other")
    print(f"{'false positives':<22}{'tracker':<16}" + "".join(f"{h:>13}" for h in heads)
          + " |" + "".join(f"{h:>11}" for h in SHAPES))
    total = {t: dict.fromkeys(CLASSES + SHAPES, 0) for t in trackers}
    for r in results:
        for t in trackers:
            fp = r.scores.get(t, {}).get("fp_causes")
            if fp is None:
                continue
            fp = fp | r.scores[t]["fp_shapes"]
            for c in CLASSES + SHAPES:
                total[t][c] += fp[c]
            print(f"{r.clip if t == trackers[0] else '':<22}{t:<16}"
                  + "".join(f"{fp[c]:13d}" for c in CLASSES) + " |"
                  + "".join(f"{fp[c]:11d}" for c in SHAPES))
    for t in trackers:
        print(f"{'sum' if t == trackers[0] else '':<22}{t:<16}"
              + "".join(f"{total[t][c]:13d}" for c in CLASSES) + " |"
              + "".join(f"{total[t][c]:11d}" for c in SHAPES))
    print("a tracker row no visible ground truth matches, by cause: coasted (no detection), "
          "a false detection\npassed on, a box that overlaps a detection matching the ground "
          "truth while the box does not,\nother; and by where it lies: holding half or more "
          "of several vehicles, of one (too large\nor off), inside one vehicle (0.7 of the "
          "box on it: a piece), elsewhere")
    print()


def print_counts(results: list[Result], trackers: list[str], summary: dict, kind: str,
                 truth: str, counts: str, count: str) -> None:
    """Per clip, line and direction the counts beside the hand range (or the true count);
    rows where the truth and every count are 0 are left out."""
    if not results:
        return
    head = "".join(f"{t:>16}" for t in trackers)
    hidden = truth == "true"       # synthetic: the true crossings made out of sight beside
    print(f"{kind:<44}{'line':>7}{'dir':>5}{truth:>8}{'hidden' if hidden else '':>7}{head}")
    for r in results:
        if r.error:
            print(f"{r.clip:<44}error: {r.error}")
            continue
        for k, (label, fwd, bwd) in enumerate(r.hand):
            for d, (lo, hi) in enumerate((fwd, bwd)):
                if hi == 0 and all(r.counts[t][k][d] == 0 for t in trackers):
                    continue
                hand = f"{lo}" if lo == hi else f"{lo}-{hi}"
                out_of_sight = f"{r.hidden[k][d]:>7d}" if hidden and r.hidden else f"{'':>7}"
                cells = ""
                for t in trackers:
                    c = r.counts[t][k][d]
                    e = count_error(c, lo, hi)
                    cells += f"{c:>11d}" + (f" ({e:+d})" if e else "     ")
                print(f"{r.clip[:43]:<44}{label:>7}{'fwd' if d == 0 else 'bwd':>5}"
                      f"{hand:>8}{out_of_sight}{cells}")
    for t in trackers:
        s = summary.get(t, {})
        if f"{counts}_total" in s:
            rel = s.get(f"{count}_relative_error")
            print(f"{t}: {s[f'{counts}_in_range']}/{s[f'{counts}_total']} counts "
                  f"{'exact' if truth == 'true' else 'in the hand range'}, "
                  f"{s[f'{counts}_within_1']} within 1, sum of errors "
                  f"{s[f'{count}_abs_error_sum']}"
                  + (f" ({100 * rel:.0f} % of the true total)" if truth == "true" else "")
                  + f", worst {100 * s[f'{count}_worst_relative']:.0f} %")
    ceiling = summary.get("synth_counts_ceiling")
    if hidden and ceiling:
        n, k = ceiling["line_directions"], ceiling["with_hidden_crossing"]
        print(f"hidden: true crossings made out of sight (the vehicle not seen on one side of "
              f"the line;\noracle.hidden_crossings): {k} of {n} line-directions hold one, so "
              f"at most {n - k} counts\nare exact for a counter that counts what it sees")
    print()


def _git_rev() -> str:
    res = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True, check=False)
    dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "vtrack"],
                           capture_output=True, text=True, check=False).stdout.strip()
    return res.stdout.strip() + ("+dirty" if dirty else "")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default=",".join(SCENES), help="presets, comma-separated")
    ap.add_argument("--seeds", default="0,1,2", help="seeds per preset")
    ap.add_argument("--frames", type=int, default=300, help="frames per synthetic clip")
    ap.add_argument("--no-large", action="store_true", help="skip the 1280x720 clip")
    ap.add_argument("--no-real", action="store_true", help="skip the real clips")
    ap.add_argument("--no-peers", action="store_true", help="vtrack only")
    ap.add_argument("--only", default="",
                    help="run only clips whose name contains one of these (comma-separated)")
    ap.add_argument("--quick", action="store_true",
                    help="one 150-frame clip per preset and two real clips")
    ap.add_argument("--config", help="a TOML config instead of the defaults")
    ap.add_argument("--without", default="", metavar="LIST",
                    help="render the perspective clips without these nuisances of `vtrack "
                         "synth` (comma-separated: shadows, exposure, shake, ...)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--work", default="/tmp/vtrack-suite/runs", help="run folders")
    ap.add_argument("--cache", default="/tmp/vtrack-suite/cache", help="rendered clips")
    ap.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    args = ap.parse_args(argv)

    scenes = [s for s in args.scenes.split(",") if s]
    seeds = [int(s) for s in args.seeds.split(",") if s]
    without = tuple(sorted(n for n in args.without.split(",") if n))
    unknown = [n for n in without if n not in NUISANCES]
    if unknown:
        ap.error(f"--without: unknown nuisance {unknown[0]!r} (one of {', '.join(NUISANCES)})")
    clips: list[SynthClip | RealClip]
    if args.quick:
        clips = [SynthClip(s, seeds[0], 150, without=without) for s in scenes]
        clips += [c for c in real_clips() if c.name.startswith(("bgslibrary", "mrc"))]
    else:
        clips = list(synthetic_clips(scenes, seeds, args.frames, not args.no_large, without))
        clips += [] if args.no_real else real_clips()
    keys = [k for k in args.only.split(",") if k]
    clips = [c for c in clips if not keys or any(k in c.name for k in keys)]
    trackers = ["vtrack"] + ([] if args.no_peers else [*PEERS, APPEARANCE_PEER])
    work, cache = Path(args.work), Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = [pool.submit(run_clip, c, work, cache, args.config, not args.no_peers)
                   for c in clips]
        results = [f.result() for f in futures]
    wall = time.perf_counter() - t0
    summary = summarise(results, trackers)
    print_table(results, trackers, summary)
    print(f"\n{len(results)} clips in {wall:.0f} s wall ({args.workers} workers); "
          f"vtrack {_git_rev()}, config {args.config or 'default'}"
          + (f", without {','.join(without)}" if without else ""))
    if args.json:
        Path(args.json).write_text(json.dumps({
            "revision": _git_rev(), "config": args.config or "default",
            "without": list(without),
            "wall_seconds": wall, "summary": summary,
            "results": [asdict(r) for r in results]}, indent=1))
    return 1 if any(r.error for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
