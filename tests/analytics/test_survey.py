"""Gates and turning movements, speeds at the count lines: the gate rule on paths, the
binned rows, the config keys, the run's files against the truth, and scripts/eval_survey.py
on a tiny input."""

from __future__ import annotations

import csv
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from vtrack.analytics.bins import TimeBins, count_rows, speed_rows
from vtrack.analytics.gates import GateCounter
from vtrack.cli import main
from vtrack.errors import InputError
from vtrack.vision.appearance import VEHICLE_CLASSES


def _csv(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _gates() -> GateCounter:
    return GateCounter(["A", "B", "P"], [np.array([[100, 0], [100, 200]]),
                                         np.array([[300, 0], [300, 200]]),
                                         np.array([[400, 50], [450, 50], [450, 100],
                                                   [400, 100]])], [True, True, False])


def test_a_track_moves_from_its_first_gate_to_its_last():
    g = _gates()
    for k, x in enumerate(range(50, 480, 10)):         # through A, B and into P
        g.add(1, k, k / 10, np.array([x, 75.0]))
    for k, x in enumerate(range(50, 200, 10)):         # A only
        g.add(2, k, k / 10, np.array([x, 75.0]))
    for k, x in enumerate(range(420, 200, -10)):       # starts inside P, then crosses B
        g.add(3, k, k / 10, np.array([x, 75.0]))
    for k, x in enumerate([90, 110, 90, 110, 90]):     # A back and forth: one gate
        g.add(4, k, k / 10, np.array([x, 75.0]))
    m1, m2, m3, m4 = (g.end_track(t) for t in (1, 2, 3, 4))
    assert (m1.origin, m1.destination) == ("A", "P")
    assert m1.time == pytest.approx((400 - 50) / 10 / 10)      # first centre inside P
    assert m2 is None and m4 is None
    assert (m3.origin, m3.destination, m3.time) == ("P", "B", pytest.approx(1.3))  # x = 290
    counts = {(m["from"], m["to"]): m["count"] for m in g.summary()}
    assert len(counts) == 6 and counts[("A", "P")] == counts[("P", "B")] == 1
    assert sum(counts.values()) == 2 and g.pending_from() is None


def test_bins_write_zeros_and_speed_percentiles():
    bins = TimeBins(10.0)
    bins.start(0.0)
    for v in (30.0, 40.0, 50.0, 60.0):
        bins.add(3.0, ("L", "forward"), "car", v)
        bins.add(3.0, ("L", "forward"), "all", v)
    bins.add(12.0, ("L", "forward"), "unknown", 20.0)
    bins.add(12.0, ("L", "forward"), "all", 20.0)
    out = bins.pop_final(12.0, None, run_end=15.0)
    keys = [("L", "forward"), ("L", "backward")]
    rows = speed_rows(out, keys, ("car", "van"))
    assert rows[:3] == [["0", "10", "L", "forward", "car", 4, "45.00", "45.00", "55.50",
                         "60.00"],
                        ["0", "10", "L", "forward", "van", 0, "", "", "", ""],
                        ["0", "10", "L", "forward", "all", 4, "45.00", "45.00", "55.50",
                         "60.00"]]
    assert [r[4] for r in rows if r[0] == "10" and r[3] == "forward"] == [
        "car", "van", "unknown", "all"]
    assert rows[-1] == ["10", "15", "L", "backward", "all", 0, "", "", "", ""]
    counts = count_rows(out, [("A", "B"), ("B", "A")], ("all",))
    assert counts[0] == ["0", "10", "A", "B", "all", 0] and len(counts) == 4


@pytest.mark.parametrize("text, message", [
    ('[[gates]]\nname = "a"', "give either line"),
    ('[[gates]]\nname = "a"\nline = [[0, 0], [1, 1]]\npolygon = [[0, 0], [1, 0], [0, 1]]',
     "give either line"),
    ('[[gates]]\nname = "a"\nline = [[0, 0], [1, 1], [2, 2]]', "exactly two points"),
    ('[[gates]]\nname = "a"\nline = [[0, 0], [0, 0]]', "zero length"),
    ('[[gates]]\nname = "a"\npolygon = [[0, 0], [10, 10], [10, 0], [0, 10]]', "edges cross"),
    ('[[gates]]\nname = "a"\nline = [[0, 0], [1.5, 1]]\nunits = "fraction"', "within 0..1"),
    ('[[gates]]\nname = "a"\nline = [[0, 0], [1, 1]]\n[[gates]]\nname = "a"\n'
     'line = [[5, 0], [1, 1]]', "two gates are named 'a'"),
    ('[[gates]]\nline = [[0, 0], [1, 1]]', "missing 'name'"),
    ('[[gates]]\nname = "a"\nline = [[0, 0], [1, 1]]\nwidth = 3', "unknown key 'width'"),
])
def test_bad_gates_are_refused_by_config_check(tmp_path, text, message, capsys):
    from vtrack.app.config import load

    cfg = tmp_path / "cfg.toml"
    cfg.write_text(text + "\n")
    with pytest.raises(InputError, match=message):
        load(cfg)
    assert main(["config", "--check", str(cfg)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and str(cfg) in err[0]


def test_config_knows_gates(tmp_path, capsys):
    assert main(["config", "--defaults"]) == 0
    defaults = capsys.readouterr().out
    assert "\ngates = []\n" in defaults and "[[gates]]" in defaults
    cfg = tmp_path / "cfg.toml"
    cfg.write_text('[[gates]]\nname = "n"\nline = [[0, 0.5], [1, 0.5]]\nunits = "fraction"\n'
                   '[[gates]]\nname = "s"\npolygon = [[0, 0], [5, 0], [5, 5]]\n')
    assert main(["config", "--check", str(cfg)]) == 0
    assert "ok" in capsys.readouterr().out


GATES = """\
[[gates]]
name = "left"
line = [[0.1, 0.0], [0.1, 1.0]]
units = "fraction"
[[gates]]
name = "middle"
line = [[320, 0], [320, 360]]
[[gates]]
name = "right"
polygon = [[0.9, 0.0], [1.0, 0.0], [1.0, 1.0], [0.9, 1.0]]
units = "fraction"
"""


def test_run_writes_movements_against_the_truth(synth_video, tmp_path, load_script):
    """Without a calibration: movements.csv's zeros for every ordered pair, bin and
    appearance class (the default detector is hybrid), its sums equal summary.json's, and the counts equal the true vehicles' own passes
    through the same gates (eval_survey on gt.csv) within one per movement; speeds.csv has
    its header only."""
    src = synth_video(0)
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(GATES)
    out = tmp_path / "run"
    assert main(["track", str(src / "video.avi"), "--out", str(out), "--quiet",
                 "--config", str(cfg), "--count-line", "50%,0%,50%,100%",
                 "--bin-seconds", "4"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["calibration"] is None
    rows = _csv(out / "movements.csv")
    assert list(rows[0]) == ["bin_start_s", "bin_end_s", "from", "to", "class", "count"]
    pairs = {(r["from"], r["to"]) for r in rows}
    assert len(pairs) == 6 and all(a != b for a, b in pairs)
    listed = [r for r in rows if r["class"] in VEHICLE_CLASSES]
    assert len(listed) == 6 * len({r["bin_start_s"] for r in rows}) * len(VEHICLE_CLASSES)
    assert {r["class"] for r in rows} - set(VEHICLE_CLASSES) <= {"unknown"}
    binned = defaultdict(int)
    for r in rows:
        binned[(r["from"], r["to"])] += int(r["count"])
    moves = {(m["from"], m["to"]): m["count"] for m in summary["movements"]}
    assert dict(binned) == moves
    assert (out / "speeds.csv").read_text() == ("bin_start_s,bin_end_s,line,direction,class,"
                                                "count,mean_kmh,p50_kmh,p85_kmh,max_kmh\n")
    res = load_script("eval_survey").evaluate_movements(src, out)
    print("overhead seed 0 movements:", res)
    assert res["true"] >= 8
    assert all(abs(m["counted"] - m["true"]) <= 1 for m in res["movements"])


def test_calibrated_run_speeds_at_the_lines_against_the_truth(synth_video, overhead_truth,
                                                              tmp_path, load_script):
    """speeds.csv per bin, line, direction and class: the `all` counts equal counts.csv's
    crossings, the class rows add up to it, and the p85 is near the truth's at its own
    crossings of the same lines (eval_survey on gt.csv and world.csv)."""
    src = synth_video(0)
    truth = tmp_path / "truth"
    overhead_truth(0, truth)
    (truth / "gt.csv").write_bytes((src / "gt.csv").read_bytes())
    out = tmp_path / "run"
    assert main(["track", str(src / "video.avi"), "--out", str(out), "--quiet",
                 "--calibration", str(truth / "calibration.toml"), "--bin-seconds", "5",
                 "--count-line", "320,0,320,360", "--count-line", "25%,0%,25%,100%"]) == 0
    speeds = _csv(out / "speeds.csv")
    counts = defaultdict(int)
    for r in _csv(out / "counts.csv"):
        counts[(r["bin_start_s"], r["line"], r["direction"])] += int(r["count"])
    every = {(r["bin_start_s"], r["line"], r["direction"]): int(r["count"])
             for r in speeds if r["class"] == "all"}
    assert every == counts and sum(every.values()) > 10
    per_class = defaultdict(int)
    for r in speeds:
        if r["class"] != "all":
            per_class[(r["bin_start_s"], r["line"], r["direction"])] += int(r["count"])
    assert per_class == every
    for r in speeds:
        if int(r["count"]):
            assert float(r["p50_kmh"]) <= float(r["p85_kmh"]) <= float(r["max_kmh"])
    res = load_script("eval_survey").evaluate_speeds(truth, out)
    print("overhead seed 0 speeds:", {k: v for k, v in res.items() if k != "bins"})
    assert res["compared"] >= 4 and res["p85_mae_kmh"] < 1.5     # measured 0.49


def _write_csv(path: Path, header: str, rows: list[str]) -> None:
    path.write_text(header + "\n" + "".join(r + "\n" for r in rows))


def test_eval_survey_on_a_tiny_input(tmp_path, load_script):
    """Two true vehicles at 10 fps: vehicle 1 through gates A and B and over line L
    (forward) at frame 4, vehicle 2 through A only and over L at frame 13; the run counted
    A -> B once and measured one speed per crossing."""
    ev = load_script("eval_survey")
    synth, run = tmp_path / "synth", tmp_path / "run"
    synth.mkdir()
    run.mkdir()
    gt, world = [], []
    for f in range(1, 9):                     # vehicle 1: centre x = 50 f + 10 (60 .. 410)
        gt.append(f"{f},1,{50 * f},90,20,20,1,-1,-1,-1,1")
        world.append(f"{f},1,{f},0,{40 + f},4.5,car")
    for f in range(10, 15):                   # vehicle 2: centre x = 50 (f - 9) + 10 .. 260
        gt.append(f"{f},2,{50 * (f - 9)},90,20,20,1,-1,-1,-1,1")
        world.append(f"{f},2,{f},0,{60 + f},4.5,car")
    (synth / "gt.csv").write_text("".join(r + "\n" for r in gt))
    # the run tracked vehicle 1 as one track and vehicle 2 as two, split at frame 12
    tracks = []
    for r in gt:
        f, tid, rest = r.split(",", 2)
        tid = "3" if tid == "2" and int(f) >= 12 else tid
        tracks.append(",".join([f, tid, rest.rsplit(",", 1)[0]]))
    (run / "tracks.csv").write_text("".join(r + "\n" for r in tracks))
    _write_csv(synth / "world.csv", "frame,id,X_m,Y_m,speed_kmh,length_m,class", world)
    (run / "summary.json").write_text(json.dumps({
        "fps_video": 10.0, "bin_seconds": 1.0,
        "gates": [{"name": "A", "line": [[100, 0], [100, 200]]},
                  {"name": "B", "line": [[300, 0], [300, 200]]}],
        "counts": [{"name": "L", "line": [200, 0, 200, 200]}]}))
    _write_csv(run / "movements.csv", "bin_start_s,bin_end_s,from,to,class,count",
               ["0,10,A,B,all,1", "0,10,B,A,all,0", "10,20,A,B,all,0", "10,20,B,A,all,1"])
    _write_csv(run / "speeds.csv", "bin_start_s,bin_end_s,line,direction,class,count,"
               "mean_kmh,p50_kmh,p85_kmh,max_kmh",
               ["0,1,L,backward,all,1,45.00,45.00,45.00,45.00",
                "1,2,L,backward,all,1,70.00,70.00,70.00,70.00"])
    moves = ev.evaluate_movements(synth, run)
    assert moves["movements"] == [{"from": "A", "to": "B", "true": 1, "counted": 1},
                                  {"from": "B", "to": "A", "true": 0, "counted": 1}]
    assert (moves["true"], moves["counted"], moves["abs_error"]) == (1, 2, 1)
    # vehicle 2 crosses A (x = 100) between frames 10 and 11: in its first track
    assert moves["passes"] == {"A": {"tracked": 2, "true": 2}, "B": {"tracked": 1, "true": 1}}
    speeds = ev.evaluate_speeds(synth, run)
    # vehicle 1's centre passes x = 200 between frames 3 (160) and 4 (210): 44 km/h at
    # frame 4 (0.3 s, bin 0); vehicle 2's between frames 12 (160) and 13 (210): 73 km/h
    # at frame 13 (1.2 s, bin 1)
    assert [(b["bin_start_s"], b["p85_true_kmh"], b["p85_error_kmh"]) for b in
            speeds["bins"]] == [(0.0, 44.0, 1.0), (1.0, 73.0, -3.0)]
    assert speeds["p85_mae_kmh"] == 2.0 and speeds["p85_bias_kmh"] == -1.0


def _crossing(folder: Path, height: int) -> None:
    """calibration.toml and world.csv of two roads crossing at the world origin, seen from
    straight above (10 px per metre, north up, the crossing at pixel (320, 320)) in a
    640 x `height` picture, vehicles along both within 30 m, 2 m either side of the axes."""
    (folder / "calibration.toml").write_text(f"frame_size = [640, {height}]\n" + "".join(
        f"[[points]]\nimage = [{320 + 10 * x}, {320 - 10 * y}]\nworld = [{x}, {y}]\n"
        for x, y in ((-10, -10), (10, -10), (10, 10), (-10, 10))))
    rows = [f"{k},{k},{s},{lat},50,4.5,car" for k, (s, lat) in enumerate(
        (s, lat) for s in range(-30, 31) for lat in (-2, 2))]
    rows += [f"{1000 + k},{k},{lat},{s},50,4.5,car" for k, (s, lat) in enumerate(
        (s, lat) for s in range(-30, 31) for lat in (-2, 2))]
    _write_csv(folder / "world.csv", "frame,id,X_m,Y_m,speed_kmh,length_m,class", rows)


def test_eval_survey_puts_gates_across_the_approaches(tmp_path, load_script):
    """A crossing of two roads seen from straight above (10 px per metre, north up): one
    gate across each approach, beyond the crossing road."""
    ev = load_script("eval_survey")
    _crossing(tmp_path, 640)
    text = ev.regions_toml(tmp_path, "gates")
    import tomllib

    gates = {g["name"]: g["line"] for g in tomllib.loads(text)["gates"]}
    # half-length 2 + 1.5 m; 3.5 + 4 m beyond the centre: 75 px from the image centre
    assert gates == {"east": [[395.0, 355.0], [395.0, 285.0]],
                     "north": [[355.0, 245.0], [285.0, 245.0]],
                     "west": [[245.0, 355.0], [245.0, 285.0]],
                     "south": [[355.0, 395.0], [285.0, 395.0]]}


def test_eval_survey_cuts_gates_to_the_picture_in_view(tmp_path, load_script):
    """--in-view: a gate reaching out of the picture is cut 5 % inside its edges; one whose
    part in view is under half of it is moved out along its approach, or there is none."""
    ev = load_script("eval_survey")
    w, h = 640, 360
    # across the picture's right edge: 80 % inside the 5 % margin (x 320 .. 608 of 320 .. 680)
    cut = ev._inside(np.array([[320.0, 100.0], [680.0, 100.0]]), w, h)
    np.testing.assert_allclose(cut, [[320.0, 100.0], [608.0, 100.0]])
    assert ev._inside(np.array([[600.0, 100.0], [900.0, 100.0]]), w, h) is None   # 3 %
    assert ev._inside(np.array([[700.0, 10.0], [700.0, 300.0]]), w, h) is None    # outside
    # the junction of test_eval_survey_puts_gates_across_the_approaches in a 640x400
    # picture: the west gate (x 245) is in view; the south gate (y 395) lies below the
    # margin (y 380), and farther out along its approach the gate only goes lower: none
    _crossing(tmp_path, 400)
    import tomllib

    every = {g["name"] for g in tomllib.loads(ev.regions_toml(tmp_path, "gates"))["gates"]}
    seen = {g["name"]: g["line"] for g in
            tomllib.loads(ev.regions_toml(tmp_path, "gates", in_view=True))["gates"]}
    assert every == {"east", "north", "west", "south"}
    assert seen["west"] == [[245.0, 355.0], [245.0, 285.0]]
    assert "south" not in seen
    assert all(0.05 * 640 <= x <= 0.95 * 640 and 0.05 * 400 <= y <= 0.95 * 400
               for line in seen.values() for x, y in line)


def test_eval_survey_in_view_truth_counts_only_movements_seen(tmp_path, load_script):
    """--in-view: a true vehicle passes a gate only where its rows are in view (at least
    MIN_VISIBILITY visible): one hidden while it crosses gate A makes no movement."""
    ev = load_script("eval_survey")
    synth, run = tmp_path / "synth", tmp_path / "run"
    synth.mkdir()
    run.mkdir()
    gt = []
    for vid, hidden in ((1, ()), (2, range(1, 5))):     # vehicle 2 unseen in frames 1-4
        for f in range(1, 9):
            vis = 0.1 if f in hidden else 1.0
            gt.append(f"{f},{vid},{50 * f},{90 + 40 * vid},20,20,1,-1,-1,-1,{vis}")
    (synth / "gt.csv").write_text("".join(r + "\n" for r in gt))
    (run / "tracks.csv").write_text("")
    (run / "summary.json").write_text(json.dumps({
        "fps_video": 10.0, "bin_seconds": 1.0,
        "gates": [{"name": "A", "line": [[100, 0], [100, 300]]},
                  {"name": "B", "line": [[300, 0], [300, 300]]}], "counts": []}))
    _write_csv(run / "movements.csv", "bin_start_s,bin_end_s,from,to,class,count",
               ["0,10,A,B,all,1"])
    assert ev.evaluate_movements(synth, run)["true"] == 2
    seen = ev.evaluate_movements(synth, run, in_view=True)
    assert seen["true"] == 1 and seen["matched"] == 1
    assert seen["passes"]["A"]["true"] == 1 and seen["passes"]["B"]["true"] == 2


def test_speed_at_a_moment_is_the_road_displacement_over_one_second():
    """Positions 10 m/s along X at 25 fps, with a per-frame speed that is off by 20 %: the
    speed at a moment comes from the displacement over CROSSING_WINDOW_S, final once the
    trace reaches past the window; a single sample gives its own speed."""
    from vtrack.analytics.vehicles import CROSSING_WINDOW_S, SpeedTrace

    trace = SpeedTrace()
    assert trace.speed_at(1.0)[1] is False
    for k in range(25):
        trace.add(k / 25, 12.0, np.array([10.0 * k / 25, 3.0]))
    v, final = trace.speed_at(0.3)
    assert v == pytest.approx(10.0) and final               # 0.0 .. 0.8 s, inside the trace
    v, final = trace.speed_at(0.8)                           # the window ends after the trace
    assert v == pytest.approx(10.0) and not final
    one = SpeedTrace()
    one.add(0.0, 12.0, np.array([0.0, 0.0]))
    assert one.speed_at(0.0)[0] == 12.0 and CROSSING_WINDOW_S == 1.0
