"""`vtrack track` on live sources (a local MJPEG camera each test starts), outputs that stay
valid when the run is killed, the decoder's messages kept off the terminal, and the
annotated video read back."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from vtrack.cli import main
from vtrack.evaluation.mot import read_mot
from vtrack.io.video import ABORT_HOOK_ENV

ROOT = Path(__file__).resolve().parents[2]
ENV = dict(os.environ, PYTHONPATH=str(ROOT))


def _vtrack(*args: str, env: dict | None = None, timeout: float = 120
            ) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "vtrack", "track", *args], env=env or ENV,
                          capture_output=True, text=True, timeout=timeout)


def _check_outputs(out: Path) -> tuple[dict, np.ndarray, list[dict]]:
    """Parse summary.json, tracks.csv and crossings.csv strictly; tracks sorted."""
    summary = json.loads((out / "summary.json").read_text())
    text = (out / "tracks.csv").read_text()
    assert text == "" or text.endswith("\n")
    rows = read_mot(out / "tracks.csv") if text else np.zeros((0, 10))
    assert np.array_equal(np.lexsort((rows[:, 1], rows[:, 0])), np.arange(len(rows)))
    with open(out / "crossings.csv", newline="") as fh:
        crossings = list(csv.DictReader(fh))
    assert all(set(c) == {"frame", "time_s", "id", "line", "direction"} for c in crossings)
    return summary, rows, crossings


def test_stream_that_drops_is_reconnected_and_tracked_on(mjpeg_camera, clip_jpegs, tmp_path,
                                                         capfd):
    camera = mjpeg_camera(clip_jpegs, fps=25.0, cut_after=60, down_for=1.0)
    assert main(["track", camera.url, "--out", str(tmp_path), "--quiet", "--max-frames", "150",
                 "--reconnect-seconds", "10", "--count-line", "320,0,320,360"]) == 0
    assert capfd.readouterr().err == ""
    summary, rows, crossings = _check_outputs(tmp_path)
    print(f"live: reconnects {summary['reconnects']}, dropped {summary['dropped_frames']}, "
          f"{summary['tracks']} tracks, counts {summary['counts']}")
    assert summary["video"] == camera.url and summary["live"] is True
    assert summary["reconnects"] >= 1 and summary["dropped_frames"] >= 0
    assert summary["complete"] is True and summary["stopped_by"] == "max-frames"
    assert summary["frames"] == 150
    # the first connection delivered at most 60 frames: these come after the reconnection
    after = rows[rows[:, 0] > 70]
    assert len(after) > 0
    first_frame = {tid: rows[rows[:, 1] == tid, 0].min() for tid in np.unique(rows[:, 1])}
    assert any(f > 70 for f in first_frame.values()), "tracks started after the reconnection"


def test_stream_that_never_comes_back_exits_2_with_valid_outputs(mjpeg_camera, clip_jpegs,
                                                                 tmp_path, capfd):
    camera = mjpeg_camera(clip_jpegs, fps=25.0, cut_after=40, down_for=None)
    assert main(["track", camera.url, "--out", str(tmp_path), "--quiet",
                 "--reconnect-seconds", "1"]) == 2
    err = capfd.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {camera.url}: source lost"), err
    summary, rows, _ = _check_outputs(tmp_path)
    assert summary["complete"] is False and summary["stopped_by"] == "error"
    assert summary["live"] is True and 1 <= summary["frames"] <= 40
    assert summary["error"] in err[0]
    assert len(rows) == 0 or rows[:, 0].max() <= summary["frames"]


def test_kill_9_during_a_live_run_leaves_valid_files(mjpeg_camera, clip_jpegs, tmp_path):
    camera = mjpeg_camera(clip_jpegs, fps=25.0)
    proc = subprocess.Popen([sys.executable, "-m", "vtrack", "track", camera.url, "--out",
                             str(tmp_path), "--quiet", "--flush-seconds", "0.5",
                             "--count-line", "320,0,320,360"], env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    summary_file = tmp_path / "summary.json"
    deadline = time.monotonic() + 90
    frames = 0
    while time.monotonic() < deadline and frames < 100:
        time.sleep(0.2)
        if summary_file.exists():
            frames = json.loads(summary_file.read_text())["frames"]
    children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
    decoder = [int(pid) for pid in children.read_text().split()] if children.exists() else []
    proc.send_signal(signal.SIGKILL)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL and err == b""
    deadline = time.monotonic() + 10
    while decoder and time.monotonic() < deadline and Path(f"/proc/{decoder[0]}").exists():
        time.sleep(0.05)
    assert not any(Path(f"/proc/{pid}").exists() for pid in decoder), "decoder outlived it"
    summary, rows, crossings = _check_outputs(tmp_path)
    print(f"after kill -9: summary frames {summary['frames']}, {len(rows)} rows up to frame "
          f"{int(rows[:, 0].max()) if len(rows) else 0}, {summary['tracks']} tracks, "
          f"{len(crossings)} crossings, counts {summary['counts'][0]['total']}")
    assert summary["complete"] is False and summary["stopped_by"] is None
    assert summary["live"] is True and summary["frames"] >= 100
    assert len(rows) > 0 and summary["tracks"] >= 1
    # what summary.json counted was on disk before it (files first, summary last)
    assert len(np.unique(rows[:, 1])) >= summary["tracks"]
    assert len(crossings) >= summary["counts"][0]["total"]


@pytest.mark.parametrize("source", ["rtsp://127.0.0.1:9/x", "cam:99"])
def test_unreachable_live_source_is_one_error_line(tmp_path, source):
    out = tmp_path / "out"
    result = _vtrack(source, "--out", str(out), "--reconnect-seconds", "1")
    assert result.returncode == 2
    err = result.stderr.splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {source}: cannot open"), err
    assert not out.exists()


def test_decoder_abort_is_one_error_line_naming_its_log(synth_video, tmp_path):
    """The dying decoder's own words (glibc-style, written to its fd 2) end up in
    decoder.log, named in the one error line; stderr holds nothing else."""
    out = tmp_path / "out"
    result = _vtrack(str(synth_video(0) / "video.avi"), "--out", str(out), "--quiet",
                     env=dict(ENV, **{ABORT_HOOK_ENV: "30"}))
    assert result.returncode == 2
    err = result.stderr.splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "after 30 frames" in err[0], err
    assert err[0].endswith(f"(decoder messages in {out / 'decoder.log'})")
    assert "malloc_consolidate()" in (out / "decoder.log").read_text()
    summary, rows, _ = _check_outputs(out)
    assert summary["complete"] is False and summary["frames"] == 30


def test_corrupt_file_keeps_ffmpeg_messages_in_the_log(synth_video, tmp_path):
    data = bytearray((synth_video(0) / "video.avi").read_bytes())
    start = len(data) // 4    # around frame 60 of 250
    data[start:start + 30000] = np.random.default_rng(1).integers(0, 256, 30000,
                                                                   np.uint8).tobytes()
    video = tmp_path / "corrupt.avi"
    video.write_bytes(data)
    out = tmp_path / "out"
    result = _vtrack(str(video), "--out", str(out), "--quiet", "--max-frames", "90")
    assert result.returncode == 0 and result.stderr == ""
    assert "[OPENCV:FFMPEG:" in (out / "decoder.log").read_text()
    summary, _, _ = _check_outputs(out)
    assert summary["complete"] is True


def test_annotated_video_is_h264_yuv420p_faststart(synth_video, tmp_path, capfd, read_video):
    assert main(["track", str(synth_video(0) / "video.avi"), "--out", str(tmp_path),
                 "--quiet", "--max-frames", "40", "--save-video"]) == 0
    assert capfd.readouterr().err == ""
    got = read_video(tmp_path / "annotated.mp4")
    print(f"annotated.mp4: {got['codec']} {got['pix_fmt']} boxes {got['boxes']}")
    assert (got["codec"], got["pix_fmt"], got["frames"]) == ("h264", "yuv420p", 40)
    assert got["boxes"].index("moov") < got["boxes"].index("mdat")


def test_annotated_video_without_pyav_is_mpeg4_with_one_warning(synth_video, tmp_path,
                                                                monkeypatch, capfd, read_video):
    monkeypatch.setitem(sys.modules, "av", None)     # import av -> ImportError
    assert main(["track", str(synth_video(0) / "video.avi"), "--out", str(tmp_path),
                 "--quiet", "--max-frames", "20", "--save-video"]) == 0
    err = capfd.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("warning: ") and "MPEG-4 Part 2" in err[0]
    monkeypatch.undo()
    got = read_video(tmp_path / "annotated.mp4")
    assert (got["codec"], got["frames"]) == ("mpeg4", 20)


def test_truncated_file_is_one_error_line_with_the_decoders_reason(synth_video, tmp_path):
    """An MP4 cut before its index (moov at the end, as OpenCV writes it): exit 2, stderr
    exactly one line, FFmpeg's own reason quoted in it, no output folder."""
    import cv2

    from vtrack.io.video_writer import OpenCVWriter

    cap = cv2.VideoCapture(str(synth_video(0) / "video.avi"))
    whole = tmp_path / "whole.mp4"
    with OpenCVWriter(whole, 25.0, (640, 360)) as writer:
        for _ in range(30):
            writer.write(cap.read()[1])
    cap.release()
    video = tmp_path / "cut.mp4"
    video.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    out = tmp_path / "out"
    result = _vtrack(str(video), "--out", str(out), "--quiet")
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr == (f"error: {video}: not a readable video (OpenCV could not open "
                             f"it) (decoder said: moov atom not found)\n")
    assert not out.exists()
