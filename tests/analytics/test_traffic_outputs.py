"""End to end on the synthetic overhead video: counts.csv per bin, line, direction and class
summing to summary.json counts, fractional and named lines, vehicles.csv with and without a
calibration (speeds against the simulator's truth through scripts/eval_speed.py), and the
append-only periodic flush."""

from __future__ import annotations

import csv
import json
from collections import Counter
from pathlib import Path

import pytest

from vtrack.analytics.vehicles import CLASS_ORDER
from vtrack.vision.appearance import VEHICLE_CLASSES

from vtrack.cli import main

FRAMES, FPS = 250, 25.0


def _csv(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _check_counts(out: Path, summary: dict, classes: set[str], bin_s: float) -> None:
    rows = _csv(out / "counts.csv")
    labels = [c.get("name", str(k)) for k, c in enumerate(summary["counts"])]
    starts = sorted({float(r["bin_start_s"]) for r in rows})
    assert starts == [bin_s * k for k in range(len(starts))]
    assert float(rows[-1]["bin_end_s"]) == pytest.approx(FRAMES / FPS)
    keys = Counter((r["bin_start_s"], r["line"], r["direction"], r["class"]) for r in rows)
    assert set(keys.values()) == {1}
    listed = [k for k in keys if k[3] in classes]
    assert len(listed) == len(starts) * len(labels) * 2 * len(classes)   # zeros included
    assert {r["class"] for r in rows} - classes <= {"unknown"}   # a class no source knows
    for label, c in zip(labels, summary["counts"]):
        for d in ("forward", "backward"):
            assert sum(int(r["count"]) for r in rows
                       if r["line"] == label and r["direction"] == d) == c[d], (label, d)
    crossings = _csv(out / "crossings.csv")
    assert len(crossings) == sum(c["total"] for c in summary["counts"])


def test_calibrated_run_counts_per_class_and_speeds_against_truth(synth_video, overhead_truth,
                                                                  tmp_path, load_script):
    src = synth_video(0)
    truth = tmp_path / "truth"
    overhead_truth(0, truth)
    out = tmp_path / "run"
    assert main(["track", str(src / "video.avi"), "--out", str(out), "--quiet",
                 "--calibration", str(truth / "calibration.toml"), "--bin-seconds", "3",
                 "--count-line", "320,0,320,360", "--count-line", "20%,0%,20%,100%"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["calibration"]["points"] == 4
    assert summary["calibration"]["reprojection_rms_px"] < 1e-3
    # the default detector is hybrid: the length's classes and the appearance model's
    _check_counts(out, summary, set(CLASS_ORDER), 3.0)
    vehicles = _csv(out / "vehicles.csv")
    assert sorted(int(v["id"]) for v in vehicles) == list(range(1, summary["tracks"] + 1))
    assert all(v["class"] in CLASS_ORDER for v in vehicles)
    for v in vehicles:
        assert int(v["first_frame"]) <= int(v["last_frame"])
        assert float(v["speed_max_kmh"]) >= float(v["speed_mean_kmh"]) - 1.0
    # a counted vehicle's class in counts.csv is its class in vehicles.csv
    cls = {v["id"]: v["class"] for v in vehicles}
    per_class = Counter(cls[c["id"]] for c in _csv(out / "crossings.csv"))
    binned = Counter()
    for r in _csv(out / "counts.csv"):
        binned[r["class"]] += int(r["count"])
    assert +binned == per_class
    # speed, length and class against the simulator (the real pipeline on a rendered video)
    for name in ("gt.csv",):
        (truth / name).write_bytes((src / name).read_bytes())
    res = load_script("eval_speed").evaluate(truth, out)
    print("overhead seed 0:", {k: v for k, v in res.items() if k != "vehicles"})
    assert res["matched"] >= 11
    assert res["speed_error_kmh"]["rmse"] < 3.0
    assert res["length_error_m"]["rmse"] < 0.6
    assert res["class_accuracy"] >= 0.9


def test_fraction_lines_equal_pixel_lines_and_names(synth_video, tmp_path):
    src = synth_video(1)
    cfg = tmp_path / "cfg.toml"
    cfg.write_text('count_lines = [{name = "centre", points = [[0.5, 0], [0.5, 1]], '
                   'units = "fraction"}, [200, 0, 200, 360]]\n')
    out = tmp_path / "run"
    assert main(["track", str(src / "video.avi"), "--out", str(out), "--quiet",
                 "--config", str(cfg), "--count-line", "50%,0%,50%,100%",
                 "--count-line", "200,0,200,360", "--bin-seconds", "4"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    named, px, pct, px2 = summary["counts"]
    assert named["name"] == "centre" and "name" not in pct
    assert named["line"] == pct["line"] == [320.0, 0.0, 320.0, 360.0]
    for key in ("forward", "backward", "total"):
        assert named[key] == pct[key] and px[key] == px2[key]
    assert named["total"] > 0 and px["total"] > 0
    crossings = _csv(out / "crossings.csv")
    by_line = {label: sorted((c["frame"], c["id"], c["direction"]) for c in crossings
                             if c["line"] == label) for label in ("centre", "1", "2", "3")}
    assert by_line["centre"] == by_line["2"] and by_line["1"] == by_line["3"]
    # without a calibration the hybrid default counts per appearance class
    _check_counts(out, summary, set(VEHICLE_CLASSES), 4.0)
    vehicles = _csv(out / "vehicles.csv")
    assert len(vehicles) == summary["tracks"]
    assert all(v["speed_mean_kmh"] == v["length_m"] == "" for v in vehicles)
    assert all(v["class"] in ("", *VEHICLE_CLASSES) for v in vehicles)


@pytest.mark.parametrize("text, message", [
    ('count_lines = [{points = [[0, 0.5], [1.2, 0.5]], units = "fraction"}]', "within 0..1"),
    ('count_lines = [{points = [[0, 1], [2, 3]], units = "inch"}]', "units must be"),
    ('count_lines = [{points = [[0, 1]]}]', "exactly two points"),
    ('count_lines = [{name = "a", points = [[0, 1], [2, 3]]}, '
     '{name = "a", points = [[5, 1], [2, 3]]}]', "two count lines are named 'a'"),
    ('count_lines = [{name = "7", points = [[0, 1], [2, 3]]}]', "not a number"),
    ('count_lines = [{points = [[0, 1], [2, 3]], colour = "red"}]', "unknown key 'colour'"),
    ('[[zones]]\nname = "z"\npolygon = [[0, 0], [10, 0]]', "at least 3 vertices"),
    ('[[zones]]\nname = "z"\npolygon = [[0, 0], [10, 10], [10, 0], [0, 10]]', "edges cross"),
    ('[[zones]]\nname = "z"\npolygon = [[0, 0], [5, 0], [10, 0]]', "zero area"),
    ('[[zones]]\npolygon = [[0, 0], [5, 0], [10, 5]]', "missing 'name'"),
    ('[[zones]]\nname = "z"\npolygon = [[0, 0], [0.5, 0], [0.5, 2]]\nunits = "fraction"',
     "within 0..1"),
    ('[[zones]]\nname = "z"\npolygon = [[0, 0], [5, 0], [5, 5]]\n[[zones]]\nname = "z"\n'
     'polygon = [[0, 0], [5, 0], [5, 5]]', "two zones are named 'z'"),
])
def test_malformed_lines_and_zones_exit_2_naming_the_file(synth_video, tmp_path, capsys,
                                                         text, message):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(text + "\n")
    out = tmp_path / "run"
    assert main(["track", str(synth_video(0) / "video.avi"), "--out", str(out), "--quiet",
                 "--config", str(cfg)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {cfg}") and message in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("arg, message", [
    ("0%,60%,100,60%", "every value in % or none"),
    ("0%,60%,100%", "four finite numbers"),
    ("0%,60%,150%,60%", "within 0..1"),
    ("a,b,c,d", "expected X1,Y1,X2,Y2"),
    ("5,5,5,5", "zero length"),
])
def test_bad_count_line_options(synth_video, tmp_path, capsys, arg, message):
    assert main(["track", str(synth_video(0) / "video.avi"), "--out", str(tmp_path / "r"),
                 "--quiet", "--count-line", arg]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--count-line" in err[0] and message in err[0]
