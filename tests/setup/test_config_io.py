"""`vtrack setup` without a browser: the drawing read from and merged into a config (other
keys kept), the TOML writer, the calibration fit the page shows, the server's endpoints over
real HTTP on 127.0.0.1, and the command's exits (bad video 2, done or SIGTERM 0)."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import tomllib
import urllib.request
from pathlib import Path

import pytest

from vtrack.cli import main
from vtrack.errors import InputError
from vtrack.setup import config_io
from vtrack.setup.server import fit_points
from vtrack.setup.toml_write import dumps

ROOT = Path(__file__).resolve().parents[2]

EXISTING = """\
count_lines = [[0, 100, 640, 100], {name = "west", points = [[0.25, 0], [0.25, 1]], units = "fraction"}]

[tracker]
jerk = 12.0

[[zones]]
name = "stop"
polygon = [[0.1, 0.5], [0.4, 0.5], [0.4, 0.9]]
units = "fraction"
debounce_s = 0.5
"""


def test_toml_writer_round_trips():
    data = {"a": 1, "b": -2.5, "c": "x \"q\" \\ é\n", "d": [[1.0, 2.0], [3, 4]], "e": True,
            "f": [], "g": float("inf"), "t": {"k": [1, 2], "sub": {"z": "y"}},
            "aot": [{"name": "n", "polygon": [[0.1, 0.2]], "inner": {"q": 1}}, {"name": "m"}],
            "key with space": 3}
    assert tomllib.loads(dumps(data)) == data
    assert "polygon = [[0.1, 0.2]]" in dumps(data)    # arrays stay on one line


def test_drawing_of_a_config_in_any_units_and_merge_keeps_other_keys(tmp_path):
    cfg_path = tmp_path / "site.toml"
    cfg_path.write_text(EXISTING)
    existing = config_io.read_config(cfg_path)
    files = config_io.SetupFiles.beside(cfg_path, "clip", existing)
    assert files.calibration == tmp_path / "clip.calibration.toml"
    drawing = config_io.load_drawing(existing, files, 640, 360)
    assert drawing["lines"] == [
        {"name": "line1", "points": [[0, 100], [640, 100]], "extra": {}},
        {"name": "west", "points": [[160.0, 0.0], [160.0, 360.0]], "extra": {}}]
    assert drawing["zones"][0]["polygon"] == [[64.0, 180.0], [256.0, 180.0], [256.0, 324.0]]
    assert drawing["zones"][0]["extra"] == {"debounce_s": 0.5}
    drawing["roi"] = [[0, 50], [640, 50], [640, 360], [0, 360]]
    drawing["points"] = [{"image": [10.04, 20.0], "world": [1, 2]},
                         {"image": [30, 40], "world": None}]
    written = config_io.save_drawing(drawing, files)
    assert written == [files.calibration, cfg_path]
    saved = tomllib.loads(cfg_path.read_text())
    assert saved["tracker"] == {"jerk": 12.0}
    assert saved["count_lines"][1] == {"name": "west", "points": [[160.0, 0.0], [160.0, 360.0]],
                                       "units": "px"}
    assert saved["zones"][0]["debounce_s"] == 0.5 and saved["roi_units"] == "px"
    assert saved["calibration"] == "clip.calibration.toml"
    cal = tomllib.loads(files.calibration.read_text())
    assert cal == {"frame_size": [640, 360], "points": [{"image": [10.0, 20.0],
                                                         "world": [1.0, 2.0]}]}
    # read back: the same drawing, the calibration point included
    again = config_io.load_drawing(config_io.read_config(cfg_path), files, 640, 360)
    assert again["roi"] == drawing["roi"] and again["points"] == cal["points"]


def test_a_drawing_the_reader_would_refuse_writes_nothing(tmp_path):
    cfg_path = tmp_path / "c.toml"
    files = config_io.SetupFiles.beside(cfg_path, "clip", {})
    bad = {"width": 640, "height": 360, "lines": [
        {"name": "a", "points": [[0, 0], [10, 10]]}, {"name": "a", "points": [[5, 0], [5, 9]]}]}
    with pytest.raises(InputError, match="two count lines are named 'a'"):
        config_io.save_drawing(bad, files)
    assert not cfg_path.exists()


def test_fit_points_reports_the_fit_or_its_refusal():
    square = [{"image": [100, 100], "world": [0, 0]}, {"image": [300, 100], "world": [10, 0]},
              {"image": [300, 300], "world": [10, 10]}, {"image": [100, 301], "world": [0, 10]},
              {"image": [50, 50], "world": None}]
    fit = fit_points(square, 640, 360)
    assert fit["ok"] and fit["points"] == 4 and fit["errors"]
    assert all(isinstance(v, (int, float, dict)) for v in fit["errors"].values())
    few = fit_points(square[:3], 640, 360)
    assert not few["ok"] and "at least 4" in few["error"]


def _post(url: str, obj: dict) -> dict:
    req = urllib.request.Request(url, json.dumps(obj).encode(), method="POST",
                                 headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=10) as r:
        return json.loads(r.read())


def _start(*args: str) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen([sys.executable, "-m", "vtrack", "setup", *args, "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)))
    line = proc.stdout.readline()
    match = re.search(r"http://127\.0\.0\.1:\d+/", line)
    assert match, (line, proc.stderr.read() if proc.poll() is not None else "")
    return proc, match[0]


def test_server_over_http_then_done_and_sigterm_exit_0(synth_video, tmp_path):
    video = synth_video(0) / "video.avi"
    cfg = tmp_path / "mine.toml"
    proc, url = _start(str(video), "--config", str(cfg))
    try:
        with urllib.request.urlopen(url, timeout=10) as r:
            page = r.read().decode()
        assert "<canvas" in page and "http" not in page.replace("http-equiv", "")  # no assets
        with urllib.request.urlopen(url + "frame.jpg", timeout=10) as r:
            assert r.headers["Content-Type"] == "image/jpeg" and r.read(2) == b"\xff\xd8"
        drawing = json.loads(urllib.request.urlopen(url + "api/drawing", timeout=10).read())
        assert (drawing["width"], drawing["height"]) == (640, 360)
        drawing["lines"] = [{"name": "mid", "points": [[320, 0], [320, 360]]}]
        saved = _post(url + "api/save", drawing)
        assert saved["ok"] and saved["written"] == [str(cfg)]
        assert _post(url + "api/done", {}) == {"ok": True}
        assert proc.wait(timeout=10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert tomllib.loads(cfg.read_text())["count_lines"][0]["name"] == "mid"
    proc, url = _start(str(video), "--config", str(cfg))
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=10) == 0
    assert proc.stderr.read() == ""


def test_bad_video_is_one_error_line(tmp_path, capsys):
    bad = tmp_path / "clip.mp4"
    bad.write_bytes(b"not a video at all" * 100)
    assert main(["setup", str(bad), "--no-browser"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {bad}")
    assert main(["setup", str(tmp_path / "none.avi"), "--no-browser"]) == 2
    assert main(["setup", str(bad), "--port", "x"]) == 2
