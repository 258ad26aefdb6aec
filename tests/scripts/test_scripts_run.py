"""Every developer script (scripts/*.py) and example (examples/*.py) run once on the smallest
input that makes it do its real work, so none rots unseen. Scripts whose test lives
elsewhere: eval_suite.py (tests/evaluation/test_suite_*.py, tests/app/test_scene_suite.py),
make_bearings_csv.py (tests/commands/test_filter_cli.py). The others are run here, through
their command line, and their printed results checked."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _run(script: str, *args: str, timeout: float = 600) -> str:
    """stdout of `python SCRIPT ARGS` (it must exit 0)."""
    proc = subprocess.run([sys.executable, str(ROOT / script), *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


def _numbers(line: str) -> list[float]:
    return [float(v) for v in re.findall(r"[-+]?\d+\.?\d*(?:e[-+]?\d+)?", line)]


def test_bench_memory_with_a_count_line(synth_video):
    """The looped clip is tracked with a counting line: RSS lines every N frames, the
    summary's frame count (2 loops of 60 frames) and the line's tallies (vehicles drive
    right to left across x = 400 in this clip)."""
    clip = synth_video(0, frames=60, vehicles=6) / "video.avi"
    out = _run("scripts/bench_memory.py", clip, "--repeat", "2", "--every", "30",
               "--count-line", "400,0,400,360")
    assert "120 frames looped" in out
    rss = [_numbers(l) for l in out.splitlines() if l.startswith("frame ")]
    assert {int(r[0]) for r in rss} >= {30, 60, 90} and all(r[1] > 10 for r in rss)
    peak = re.search(r"peak rss ([0-9.]+) MB; rss growth over the second half ([-+0-9.]+) MB",
                     out)
    assert peak and float(peak.group(1)) >= max(r[1] for r in rss), out
    end = re.search(r"; (\d+) frames, (\d+) tracks", out)
    assert end and int(end.group(1)) == 120 and int(end.group(2)) >= 2
    line = re.search(r"line 0: (\d+) forward, (\d+) backward", out)
    assert line and int(line.group(1)) + int(line.group(2)) >= 2, out


@pytest.mark.slow
def test_iterated_convergence_example():
    """examples/iterated_convergence.py on one run per case: every (kind, setting) row; the
    reference setting is at distance 0 from itself and the defaults (30, 1e-4) within 0.01
    posterior standard deviations of it."""
    out = _run("examples/iterated_convergence.py", "--runs-toolbox", "1", "--runs-precise", "1")
    rows = [l for l in out.splitlines() if "iterations mean" in l]
    assert len(rows) == 2 * 2 * 4
    for l in rows:
        dist = float(re.search(r"reference ([0-9.e+-]+) std", l).group(1))
        if "max_iterations 200" in l:
            assert dist == 0.0
        if "max_iterations  30 tolerance   1e-04" in l:
            assert dist < 0.01, l
        assert float(re.search(r"rmse ([0-9.]+)", l).group(1)) < 0.5


def test_bench_adaptive_tracker():
    """One seed of 60 frames: a row per filter kind with a centre RMSE near the injected
    noise (0.5 then 3 px std) and MOTA / IDF1 of a working tracker."""
    out = _run("scripts/bench_adaptive_tracker.py", "--seeds", "1", "--frames", "60")
    rows = [l for l in out.splitlines() if l.startswith(("kf ", "ankf", "fuzzy", "siim"))]
    assert len(rows) == 7
    for l in rows:
        rmse, mota, idf1 = _numbers(l)[-3:]
        assert 0.3 < rmse < 6.0 and mota > 0.7 and idf1 > 0.7, l


def test_bench_tracker():
    """6 frames: vtrack and the two per-track baselines at 10, 100 and 1000 targets (the
    script itself checks that both baselines follow every target)."""
    out = _run("scripts/bench_tracker.py", "--frames", "6")
    rows = {int(_numbers(l)[0]): _numbers(l) for l in out.splitlines()
            if re.match(r"\s+\d+\s", l)}
    assert sorted(rows) == [10, 100, 1000]
    for n, ours, tracker, ratio, filters, ratio_f in rows.values():
        assert min(ours, tracker, filters) > 0
        # the ratio is printed to 0.1 from unrounded times; the times to 0.01 ms
        for base, r in ((tracker, ratio), (filters, ratio_f)):
            slack = 0.05 + 0.005 * (1 / ours + base / ours**2) + 1e-9
            assert r == pytest.approx(base / ours, abs=slack)


@pytest.mark.slow
def test_bench_batch():
    """Two copies of a 20-frame video with 1 and 2 workers: a row per worker count with its
    videos per minute and frames per second."""
    out = _run("scripts/bench_batch.py", "--videos", "2", "--frames", "20", "--copies")
    assert "2 copies of a synthetic video, 20 frames 640x360" in out
    rows = {int(_numbers(l)[0]): _numbers(l) for l in out.splitlines()
            if re.match(r"\s+[12]\s+\d", l)}
    assert sorted(rows) == [1, 2]
    for w, (_, seconds, per_min, fps, *_rest) in rows.items():
        assert seconds > 0 and per_min == pytest.approx(60 * 2 / seconds, rel=0.01)
        assert fps == pytest.approx(2 * 20 / seconds, rel=0.02)


def test_bench_pipeline():
    """A 30-frame 1280x720 overhead clip, stages timed by CPU time: the decode-only and
    tracked frame rates (over the frames after the first: the difference of a 30- and a
    1-frame run; a smaller clip decodes too fast for it to stand out of a busy machine's
    noise) and their ratio, and the per-frame cost of each detector and tracker stage."""
    out = _run("scripts/bench_pipeline.py", "--frames", "30", "--scene", "overhead",
               "--size", "1280x720", "--stage-clock", "cpu")
    assert out.startswith("video: 1280x720 MJPG"), out
    assert "every stage timed in one thread by its CPU time" in out
    num = r"([-+0-9.einf]+)"
    decode = float(re.search(r"decode only :\s+" + num + " fps", out).group(1))
    tracked = float(re.search(r"tracked     :\s+" + num + " fps", out).group(1))
    ratio = float(re.search(r"ratio tracked/decode: " + num, out).group(1))
    assert decode > 0 and tracked > 0, out
    assert ratio == pytest.approx(tracked / decode, rel=0.02)
    stages = dict(re.findall(r"^  (MOG2|tracker update|tracker predict)\s+([0-9.]+) ms", out,
                             re.M))
    assert len(stages) == 3 and float(stages["MOG2"]) > 0, out


def test_bench_pipeline_against_mog2_on_a_given_video(synth_video):
    """`--video` benchmarks the given clip (its own size and frames); `--against-mog2 2`
    prints two interleaved rounds of the default (hybrid) run and of MOG2 alone and the
    ratio of their summed wall times."""
    video = synth_video(0) / "video.avi"
    out = _run("scripts/bench_pipeline.py", "--video", video, "--frames", "20",
               "--against-mog2", "2")
    assert out.startswith(f"video: 640x360 {video}, 20 frames; detector hybrid"), out
    line = re.search(r"hybrid against MOG2 alone, 2 interleaved rounds .*: (.*)", out)
    rounds = [_numbers(r) for r in line.group(1).split(";")]
    assert len(rounds) == 2 and all(a > 0 and b > 0 for a, b in rounds), out
    ratio = float(re.search(r"ratio hybrid / MOG2 alone: ([0-9.]+)", out).group(1))
    # the rounds are printed to 10 ms: the ratio recomputed from them agrees within 2 %
    assert ratio == pytest.approx(sum(a for a, _ in rounds) / sum(b for _, b in rounds),
                                  rel=0.02)


def test_overhead_truth(tmp_path):
    """world.csv of a 30-frame overhead scene: frame,id,X_m,Y_m,speed_kmh,length_m,class for
    frames 1..30, plausible speeds and lengths."""
    _run("scripts/overhead_truth.py", tmp_path, "--frames", "30", "--vehicles", "4")
    lines = (tmp_path / "world.csv").read_text().splitlines()
    assert lines[0] == "frame,id,X_m,Y_m,speed_kmh,length_m,class"
    rows = [l.split(",") for l in lines[1:]]
    frames = {int(r[0]) for r in rows}
    assert frames <= set(range(1, 31)) and len(frames) > 20
    speed, length = np.array([[float(r[4]), float(r[5])] for r in rows]).T
    assert np.all((speed > 10) & (speed < 200)) and np.all((length > 2) & (length < 30))


def test_eval_speed(tmp_path, cli_stdout):
    """A calibrated 80-frame mast clip tracked by `vtrack track --calibration`: eval_speed's
    JSON pairs tracks with true vehicles (measured: 8 of 25), each error is the tracked minus
    the true mean speed, and the summary's RMSE, bias and share within 5 km/h are those of
    the per-vehicle errors."""
    synth, run = tmp_path / "synth", tmp_path / "run"
    cli_stdout(["synth", str(synth), "--scene", "mast", "--frames", "80", "--seed", "0"])
    cli_stdout(["track", str(synth / "video.avi"), "--out", str(run), "--quiet",
                "--calibration", str(synth / "calibration.toml")])
    res = json.loads(_run("scripts/eval_speed.py", synth, run, "--json"))
    tracked = [v for v in res["vehicles"] if v["track_id"] is not None]
    assert len(tracked) == res["matched"] >= 4 and res["gt_vehicles"] == len(res["vehicles"])
    for v in tracked:
        assert v["speed_error_kmh"] == pytest.approx(v["speed_kmh"] - v["speed_true_kmh"],
                                                     abs=0.05)
        assert 10 < v["speed_true_kmh"] < 200 and v["frames"] > 0
    e = np.array([v["speed_error_kmh"] for v in tracked])
    assert res["speed_error_kmh"]["rmse"] == pytest.approx(np.sqrt(np.mean(e**2)), abs=1e-3)
    assert res["speed_error_kmh"]["bias"] == pytest.approx(e.mean(), abs=1e-3)
    assert res["speed_within_5kmh"] == pytest.approx(np.mean(np.abs(e) <= 5), abs=1e-3)


def test_eval_oracle(tmp_path):
    """The tracker fed the ground-truth boxes of one 60-frame overhead clip: its MOTA, IDF1
    and HOTA near 1 (tests/tracking/test_oracle_ceiling.py holds the floors)."""
    js = tmp_path / "oracle.json"
    out = _run("scripts/eval_oracle.py", "--scenes", "overhead", "--seeds", "0", "--frames",
               "60", "--no-peers", "--cache", tmp_path / "cache", "--json", js)
    assert "overhead-0" in out
    (clip,) = json.loads(js.read_text())["results"]
    assert min(clip["scores"]["vtrack"][m] for m in ("mota", "idf1", "hota")) > 0.8, clip


@pytest.mark.skipif(not (ROOT.parent / "shared" / "videos" / "realboxes").is_dir(),
                    reason="../shared/videos/realboxes not available")
def test_eval_realboxes(tmp_path):
    """Detector recall and precision on the first 40 real NGSIM frames of each sequence
    (frames 1-10 skipped): MOG2 at the default finds most of them (0.74-0.76 recall, 0.92-0.94
    precision over the whole sequences, as measured outside)."""
    js = tmp_path / "realboxes.json"
    out = _run("scripts/eval_realboxes.py", "--max-frames", "40", "--json", js)
    assert "ngsim_us101_seq1" in out and "ngsim_us101_seq2" in out
    for name, r in json.loads(js.read_text()).items():
        assert r["true"] > 100, name
        assert 0.5 < r["recall"] <= 1 and 0.8 < r["precision"] <= 1, (name, r)


def test_eval_far(tmp_path):
    """The far-vehicle evaluation on one short 1280x720 mast clip with far vehicles: both
    configurations scored, the scores fractions (the band needs more tracked boxes than 60
    frames give to start, so the two may agree)."""
    js = tmp_path / "far.json"
    out = _run("scripts/eval_far.py", "--seeds", "102", "--frames", "60", "--work",
               tmp_path / "work", "--json", js)
    assert "mast-102" in out and "mean" in out
    (clip,) = json.loads(js.read_text()).values()
    assert set(clip) == {"far band off", "far band on"}
    for r in clip.values():
        assert r["far_boxes"] > 50
        assert all(0 <= r[k] <= 1 for k in ("recall", "far_recall", "precision", "idf1"))


def test_stabiliser_truth(tmp_path):
    """One 40-frame mast clip: the stabiliser's error against the true sway, in pixels, with
    both stabiliser settings."""
    out = _run("scripts/stabiliser_truth.py", "--scenes", "mast", "--seeds", "0", "--frames",
               "40", "--cache", tmp_path)
    (row,) = [l for l in out.splitlines() if l.startswith("mast-0")]
    vals = _numbers(row.split(None, 1)[1])
    assert len(vals) == 7 and all(0 <= v < 20 for v in vals), row


def test_readme_picture(tmp_path):
    """The 2 x 2 picture of the four scenes from 40-frame clips, tiles of 640 x 360."""
    import cv2

    pic = tmp_path / "tracking.jpg"
    out = _run("scripts/readme_picture.py", "--out", pic, "--frames", "40", "--frame", "30")
    assert f"wrote {pic} (1280x720)" in out
    image = cv2.imread(str(pic))
    assert image.shape == (720, 1280, 3) and image.std() > 10


@pytest.mark.slow
def test_ablation(tmp_path):
    """One ablation on the smallest suite (one 40-frame overhead clip, no real clips): the
    default and the ablated row with their scores, and the JSON of both."""
    js = tmp_path / "ablation.json"
    out = _run("scripts/ablation.py", "--only", "no-smoothing", "--scenes", "overhead",
               "--seeds", "0", "--frames", "40", "--no-real", "--cache", tmp_path / "cache",
               "--json", js)
    rows = {l.split()[0]: l for l in out.splitlines() if l.startswith(("default", "no-"))}
    assert sorted(rows) == ["default", "no-smoothing"]
    data = json.loads(js.read_text())
    assert sorted(data) == ["default", "no-smoothing"]
    for name, row in rows.items():
        assert f"{data[name]['mota_mean']:7.3f}" in row
        assert 0.5 < data[name]["mota_mean"] <= 1.0


def test_bench_experiments():
    """Two runs of the ankf experiment stacked (on the default workers and on one) and one run
    at a time (the loop measured at one run and scaled), and the per-update cost of two
    kinds: a line each with its figures."""
    out = _run("scripts/bench_experiments.py", "--names", "ankf", "--runs", "2",
               "--loop-runs", "1", "--no-default", "--kinds", "iekf,srukf",
               "--update-runs", "2", "--steps", "3")
    for kind in ("iekf", "srukf"):
        line = next(l for l in out.splitlines() if l.startswith(f"update {kind}:"))
        assert "stacked" in line and "ratio" in line and all(v > 0 for v in _numbers(line))
    exp = next(l for l in out.splitlines() if l.startswith("experiment ankf runs 2:"))
    assert "measured at 1 runs, scaled" in exp and "CPU ratio" in exp
    assert re.search(r"s CPU on [0-9]+ workers, [0-9.]+ s wall [0-9.]+ s CPU on 1 \(wall ratio "
                     r"[0-9.]+\)", exp), exp
    assert re.search(r"all 1 experiments at 2 runs: stacked [0-9.]+ s wall [0-9.]+ s CPU on "
                     r"[0-9]+ workers, [0-9.]+ s wall [0-9.]+ s CPU on 1 \(wall ratio [0-9.]+\), "
                     r"one run at a time [0-9.]+ s wall [0-9.]+ s CPU", out), out
