"""vtrack batch on the local engine: inputs, naming, batch.csv, failures, re-runs, identical
outputs to `vtrack track`, interruption."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from vtrack.batch.inputs import discover, output_names
from vtrack.cli import main
from vtrack.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
COLUMNS = ["video", "out", "status", "frames", "fps_processed", "tracks", "error"]


def _copy(src: Path, dst: Path) -> Path:
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dst)
    return dst


def _read_batch(out: Path) -> list[dict]:
    with open(out / "batch.csv", newline="") as fh:
        reader = csv.DictReader(fh)
        assert reader.fieldnames == COLUMNS
        return list(reader)


def _error_lines(err: str) -> list[str]:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return lines


@pytest.fixture
def tree(tmp_path, clip_factory):
    """videos/cam1/0800.avi, videos/cam2/0800.avi (same stem), videos/.hidden/x.avi,
    videos/cam2/notes.txt, loose/single.avi, globbed/a.avi, globbed/deep/b.avi,
    bad/broken.mp4 (not a video)."""
    _copy(clip_factory(40, 0), tmp_path / "videos" / "cam1" / "0800.avi")
    _copy(clip_factory(40, 1), tmp_path / "videos" / "cam2" / "0800.avi")
    _copy(clip_factory(40, 1), tmp_path / "videos" / ".hidden" / "x.avi")
    (tmp_path / "videos" / "cam2" / "notes.txt").write_text("not a video\n")
    _copy(clip_factory(40, 2), tmp_path / "loose" / "single.avi")
    _copy(clip_factory(40, 3), tmp_path / "globbed" / "a.avi")
    _copy(clip_factory(40, 4), tmp_path / "globbed" / "deep" / "b.avi")
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "broken.mp4").write_bytes(os.urandom(4096))
    return tmp_path


# ------------------------------------------------------------------ inputs and naming
def test_discover_files_folders_and_globs(tree, monkeypatch):
    monkeypatch.chdir(tree)
    out = tree / "out"
    # an earlier batch's outputs inside a scanned folder must not be picked up as inputs
    _copy(tree / "loose" / "single.avi", out / "single" / "annotated.mp4")
    found = discover(["videos", "globbed/**/*.avi", "loose/single.avi", "loose/single.avi",
                      "videos/cam1/0800.avi", "."], exclude=out)
    assert [str(p) for p in found[:5]] == [
        "videos/cam1/0800.avi", "videos/cam2/0800.avi",        # folder, sorted, no hidden
        "globbed/a.avi", "globbed/deep/b.avi",                 # recursive glob
        "loose/single.avi",                                    # file, given twice
    ]
    # "." adds only what was not reached before (broken.mp4), never out/ or .hidden/
    assert [p.name for p in found[5:]] == ["broken.mp4"]


@pytest.mark.parametrize("bad", ["missing.avi", "globbed/*.mkv", "nowhere/**/*.avi", "empty"])
def test_input_that_matches_nothing_is_an_error(tree, monkeypatch, capsys, bad):
    monkeypatch.chdir(tree)
    (tree / "empty").mkdir()
    with pytest.raises(InputError, match=bad.replace("*", r"\*")):
        discover(["loose", bad])
    assert main(["batch", "loose", bad, "--out", "out", "--quiet"]) == 2
    assert bad in _error_lines(capsys.readouterr().err)[0]
    assert not (tree / "out").exists(), "nothing is written for bad input"


def test_colliding_stems_get_parent_folder_prefixes():
    vids = [Path(p) for p in [
        "/d/cam1/0800.avi", "/d/cam2/0800.avi",             # parent tells them apart
        "/x/day1/cam/a.mp4", "/x/day2/cam/a.mp4",           # needs two levels
        "/s/clip.avi", "/s/clip.mp4",                       # same folder: the extension
        "/q/unique.avi",
        "/r/batch.csv.avi",                                 # would clash with batch.csv
        "/t/cam1_0800.avi",                                 # clashes with a prefixed name
    ]]
    names = output_names(vids)
    assert names == ["cam1_0800", "cam2_0800", "day1_cam_a", "day2_cam_a",
                     "s_clip_avi", "s_clip_mp4", "unique", "r_batch.csv", "cam1_0800-2"]
    assert output_names(vids) == names, "deterministic"


# ------------------------------------------------------------------------ end to end
def test_batch_end_to_end_failure_isolation_rerun_and_identical_outputs(tree, monkeypatch,
                                                                        capsys):
    monkeypatch.chdir(tree)
    args = ["batch", "videos", "globbed/**/*.avi", "loose/single.avi", "bad/broken.mp4",
            "--out", "out", "--workers", "2", "--quiet"]
    t0 = time.perf_counter()
    assert main(args) == 2
    first_run = time.perf_counter() - t0
    err = _error_lines(capsys.readouterr().err)[0]
    assert "1 of 6 videos failed" in err and "broken.mp4" in err

    rows = _read_batch(tree / "out")
    assert [(r["video"], r["out"], r["status"]) for r in rows] == [
        ("videos/cam1/0800.avi", "out/cam1_0800", "ok"),
        ("videos/cam2/0800.avi", "out/cam2_0800", "ok"),
        ("globbed/a.avi", "out/a", "ok"),
        ("globbed/deep/b.avi", "out/b", "ok"),
        ("loose/single.avi", "out/single", "ok"),
        ("bad/broken.mp4", "out/broken", "failed"),
    ]
    for r in rows[:5]:
        summary = json.loads((tree / r["out"] / "summary.json").read_text())
        assert summary["complete"] is True
        assert int(r["frames"]) == summary["frames"] == 40
        assert int(r["tracks"]) == summary["tracks"]
        assert float(r["fps_processed"]) == summary["fps_processed"]
        assert r["error"] == ""
        assert {"tracks.csv", "crossings.csv"} <= {p.name for p in (tree / r["out"]).iterdir()}
    broken = rows[5]
    assert "broken.mp4" in broken["error"] and "\n" not in broken["error"]
    assert not (tree / "out" / "broken" / "summary.json").exists() or not json.loads(
        (tree / "out" / "broken" / "summary.json").read_text())["complete"]

    # the same video through `vtrack track` gives byte-identical results
    for video, name in [("loose/single.avi", "single"), ("videos/cam2/0800.avi", "cam2_0800")]:
        ref = tree / "ref" / name
        assert main(["track", video, "--out", str(ref), "--quiet"]) == 0
        for f in ("tracks.csv", "crossings.csv"):
            assert (ref / f).read_bytes() == (tree / "out" / name / f).read_bytes(), (name, f)
        a = json.loads((ref / "summary.json").read_text())
        b = json.loads((tree / "out" / name / "summary.json").read_text())
        for key in ("frames", "tracks", "counts", "width", "height", "config_hash"):
            assert a[key] == b[key], key

    # re-run: completed videos are skipped (not re-tracked), the broken one fails again
    mtime = (tree / "out" / "a" / "tracks.csv").stat().st_mtime_ns
    assert main(args) == 2
    capsys.readouterr()
    rerun = _read_batch(tree / "out")
    assert [r["status"] for r in rerun] == ["skipped"] * 5 + ["failed"]
    assert [r["frames"] for r in rerun[:5]] == [r["frames"] for r in rows[:5]]
    assert (tree / "out" / "a" / "tracks.csv").stat().st_mtime_ns == mtime

    # without the broken input every video is ok or skipped: exit 0
    t0 = time.perf_counter()
    assert main(args[:4] + args[5:]) == 0
    assert time.perf_counter() - t0 < first_run
    assert [r["status"] for r in _read_batch(tree / "out")] == ["skipped"] * 5
    # --force re-tracks a completed video
    assert main(["batch", "loose", "--out", "out", "--quiet", "--force", "--max-frames", "5"]) == 0
    assert [(r["status"], r["frames"]) for r in _read_batch(tree / "out")] == [("ok", "5")]
    print(f"first batch of 6 videos: {first_run:.1f} s")


def test_optional_outputs_and_options(tree, monkeypatch, capsys):
    pytest.importorskip("rerun")
    monkeypatch.chdir(tree)
    rc = main(["batch", "loose", "--out", "out", "--workers", "1", "--quiet", "--max-frames",
               "12", "--save-frames", "--save-video", "--rerun", "--count-line", "160,0,160,180"])
    assert rc == 0, capsys.readouterr().err
    folder = tree / "out" / "single"
    names = {p.name for p in folder.iterdir()}
    assert {"tracks.csv", "summary.json", "crossings.csv", "frames", "annotated.mp4",
            "tracks.rrd"} <= names
    assert len(list((folder / "frames").iterdir())) == 12
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["frames"] == 12 and summary["counts"][0]["line"] == [160.0, 0.0, 160.0, 180.0]


@pytest.mark.parametrize("argv,needle", [
    (["--workers", "0"], "--workers"),
    (["--address", "127.0.0.1:1"], "--address"),
    (["--max-frames", "0"], "--max-frames"),
])
def test_bad_options_exit_2(tree, monkeypatch, capsys, argv, needle):
    monkeypatch.chdir(tree)
    assert main(["batch", "loose", "--out", "out", "--quiet", *argv]) == 2
    assert needle in _error_lines(capsys.readouterr().err)[0]


@pytest.mark.parametrize("engine,pip", [("ray", "vtrack[ray]"), ("dask", "vtrack[dask]")])
def test_missing_extra_names_the_pip_command(tree, monkeypatch, capsys, engine, pip):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name in ("ray", "distributed") else real(name, *a))
    monkeypatch.chdir(tree)
    assert main(["batch", "loose", "--out", "out", "--engine", engine, "--quiet"]) == 2
    line = _error_lines(capsys.readouterr().err)[0]
    assert "pip install" in line and pip in line


# ----------------------------------------------------------------------- interruption
def _start_batch(inputs: Path, out: Path, workers: int) -> subprocess.Popen:
    """`vtrack batch INPUTS --out OUT` in a process group of its own, to be interrupted."""
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT))
    return subprocess.Popen([sys.executable, "-m", "vtrack", "batch", str(inputs),
                             "--out", str(out), "--workers", str(workers), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                            start_new_session=True)


def _children(pid: int) -> list[int]:
    kids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                kids.append(int(entry.name))
    return kids


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
def test_interrupted_batch_exits_130_and_resumes(tmp_path, clip_factory, how,
                                                 terminal_sigint):
    frames = 800
    for k in range(3):
        _copy(clip_factory(frames, 10 + k), tmp_path / "in" / f"v{k}.avi")
    out = tmp_path / "out"
    proc = _start_batch(tmp_path / "in", out, workers=2)
    deadline = time.time() + 60
    # both workers are tracking: a run writes summary.json after its first frame (before
    # that it reads the background samples, which takes a machine-dependent time)
    while time.time() < deadline and len(list(out.glob("v*/summary.json"))) < 2:
        time.sleep(0.05)
    workers = _children(proc.pid)
    if how == "ctrl-c":
        os.killpg(proc.pid, signal.SIGINT)    # a terminal's Ctrl-C reaches the whole group
    else:
        proc.send_signal(signal.SIGTERM)      # only the batch process
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert err.decode().strip() == "interrupted"
    time.sleep(0.2)
    assert workers and not [p for p in workers if _alive(p)], "no worker outlives the batch"

    rows = _read_batch(out)                   # valid, lists only finished videos
    assert all(r["status"] == "ok" for r in rows)
    done = {r["out"] for r in rows}
    flushed = 0
    for folder in sorted(p for p in out.iterdir() if p.is_dir()):
        assert not list(folder.glob(".*")), "no temporary files left"
        summary = folder / "summary.json"
        if str(folder) in done:
            assert json.loads(summary.read_text())["complete"] is True
        elif summary.exists():
            # an interrupt that lands after a video's last frame and before the run is
            # finalised leaves all its frames flushed and the run not complete
            data = json.loads(summary.read_text())
            assert data["complete"] is False and 0 < data["frames"] <= frames
            flushed += 1
    assert flushed >= 1, "an interrupted video flushes what it processed"

    if how != "ctrl-c":
        return
    # the re-run skips what finished and redoes the rest (--max-frames only keeps it short)
    assert main(["batch", str(tmp_path / "in"), "--out", str(out), "--quiet", "--max-frames",
                 "20"]) == 0
    rows2 = _read_batch(out)
    assert len(rows2) == 3
    assert {r["out"] for r in rows2 if r["status"] == "skipped"} == done
    assert all(r["status"] == "ok" and r["frames"] == "20" for r in rows2 if r["out"] not in done)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_worker_that_dies_fails_only_its_video(tmp_path, clip_factory):
    for k, (frames, seed) in enumerate([(800, 10), (40, 0), (40, 1)]):   # cached clips
        _copy(clip_factory(frames, seed), tmp_path / "in" / f"v{k}.avi")
    out = tmp_path / "out"
    proc = _start_batch(tmp_path / "in", out, workers=1)
    deadline = time.time() + 60
    while time.time() < deadline and not (out / "v0").is_dir():
        time.sleep(0.02)
    worker = [p for p in _children(proc.pid)
              if b"spawn_main" in Path(f"/proc/{p}/cmdline").read_bytes()]
    assert len(worker) == 1
    os.kill(worker[0], signal.SIGKILL)            # e.g. the OOM killer
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2, err
    assert _error_lines(err.decode())
    rows = _read_batch(out)
    assert [r["status"] for r in rows] == ["failed", "ok", "ok"]
    assert "worker process died (killed by signal 9)" in rows[0]["error"]


@pytest.mark.parametrize("when", ["after", "during"])
def test_an_interrupt_after_the_run_finished_still_counts_the_video(tmp_path, clip_factory,
                                                                     monkeypatch, when):
    """A worker interrupted between the end of a video's run (summary.json complete) and
    sending its row reports the video "ok"; one interrupted while running reports
    "interrupted" (and its summary says not complete)."""
    import vtrack.app.track as track_app
    from vtrack.app.config import AppConfig
    from vtrack.batch.task import VideoTask, process_video

    video = tmp_path / "v.avi"
    _copy(clip_factory(40, 0), video)
    real = track_app.track_video

    def interrupted(src, out, cfg, opts):
        if when == "during":
            opts.max_frames = 10                 # a run that ends early, as an interrupt
        summary = real(src, out, cfg, opts)
        if when == "during":
            (Path(out) / "summary.json").write_text(json.dumps({**summary, "complete": False}))
        raise KeyboardInterrupt

    monkeypatch.setattr(track_app, "track_video", interrupted)
    out = tmp_path / "out"
    task = VideoTask(0, str(video), str(video), str(out), str(out), AppConfig())
    result = process_video(task)
    if when == "after":
        summary = json.loads((out / "summary.json").read_text())
        assert result["status"] == "ok" and result["frames"] == summary["frames"] == 40
    else:
        assert result["status"] == "interrupted" and result["frames"] == ""
