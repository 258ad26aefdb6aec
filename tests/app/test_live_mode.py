"""`--live auto|yes|no`: a video file on a local web server that answers byte ranges (started
by each test on 127.0.0.1) is read like the file itself under `auto`; `yes` reads it live;
`no` reads a live-only MJPEG camera every frame at the tracker's pace."""

from __future__ import annotations

import contextlib
import functools
import http.server
import json
import os
import re
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import pytest

from vtrack.cli import main
from vtrack.io.video import VideoReader


class RangeHandler(http.server.SimpleHTTPRequestHandler):
    """SimpleHTTPRequestHandler plus single byte ranges (`Range: bytes=a-b`, 206), as web
    servers answer video files; `delay` seconds per response (a slow server)."""

    delay = 0.0

    def send_head(self):  # noqa: D102 - http.server's hook
        match = re.fullmatch(r"bytes=(\d*)-(\d*)", self.headers.get("Range", "").strip())
        path = Path(self.translate_path(self.path))
        if not match or not path.is_file():
            return super().send_head()
        size = path.stat().st_size
        first = int(match[1]) if match[1] else max(0, size - int(match[2] or 0))
        last = min(int(match[2]), size - 1) if match[1] and match[2] else size - 1
        if first >= size or first > last:
            self.send_error(416)
            return None
        fh = open(path, "rb")
        fh.seek(first)
        self.send_response(206)
        self.send_header("Content-Type", self.guess_type(str(path)))
        self.send_header("Accept-Ranges", "bytes")
        self.send_header("Content-Range", f"bytes {first}-{last}/{size}")
        self.send_header("Content-Length", str(last - first + 1))
        self.end_headers()
        self.range_left = last - first + 1
        return fh

    def copyfile(self, source, outputfile):  # noqa: D102
        left = getattr(self, "range_left", None)
        while left is None or left > 0:
            chunk = source.read(65536 if left is None else min(65536, left))
            if not chunk:
                break
            outputfile.write(chunk)
            if left is not None:
                left -= len(chunk)

    def log_message(self, *args: object) -> None:
        pass


class Server(http.server.ThreadingHTTPServer):
    """A client that seeks closes the connection of the range it no longer needs: quiet."""

    def handle_error(self, request, client_address) -> None:  # noqa: D102
        import sys

        if not isinstance(sys.exc_info()[1], ConnectionError):
            super().handle_error(request, client_address)


@contextlib.contextmanager
def serve(folder: Path, handler_class: type = RangeHandler) -> Iterator[str]:
    """A threaded HTTP server for `folder` on 127.0.0.1 (a free port); yields its base URL."""
    handler = functools.partial(handler_class, directory=str(folder))
    server = Server(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


@pytest.fixture(scope="module")
def served_clip(synth_video, tmp_path_factory) -> Path:
    """The seed-3 synthetic clip (250 frames) re-encoded as an MP4 (MPEG-4 Part 2, index at
    the end: a reader needs byte ranges to find it)."""
    folder = tmp_path_factory.mktemp("served")
    cap = cv2.VideoCapture(str(synth_video(3) / "video.avi"))
    out = folder / "clip.mp4"
    writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, (640, 360))
    while True:
        ok, image = cap.read()
        if not ok:
            break
        writer.write(image)
    writer.release()
    cap.release()
    return out


LINE = ["--count-line", "320,0,320,360", "--count-line", "160,0,160,360"]


def _track(source: str, out: Path, *args: str) -> dict:
    assert main(["track", source, "--out", str(out), "--quiet", *LINE, *args]) == 0
    return json.loads((out / "summary.json").read_text())


def test_http_video_of_known_length_is_read_like_the_file(served_clip, tmp_path, capfd):
    local = _track(str(served_clip), tmp_path / "file")
    with serve(served_clip.parent) as base:
        url = f"{base}/{served_clip.name}"
        remote = _track(url, tmp_path / "http")
    assert capfd.readouterr().err == ""
    print(f"file: {local['frames']} frames, counts {local['counts']}; http: "
          f"{remote['frames']} frames, dropped {remote['dropped_frames']}, live "
          f"{remote['live']}, counts {remote['counts']}")
    assert local["frames"] == 250 and local["live"] is False
    assert remote["frames"] == 250 and remote["dropped_frames"] == 0
    assert remote["live"] is False and remote["complete"] is True
    assert remote["counts"] == local["counts"] and sum(c["total"] for c in local["counts"]) > 0
    assert remote["tracks"] == local["tracks"]
    for name in ("tracks.csv", "crossings.csv", "counts.csv"):
        assert (tmp_path / "http" / name).read_bytes() == (tmp_path / "file" / name).read_bytes()


def test_live_yes_reads_the_same_http_video_live_and_drops_behind_a_slow_consumer(
        served_clip):
    with serve(served_clip.parent) as base:
        url = f"{base}/{served_clip.name}"
        got = 0
        with VideoReader(url, reconnect_seconds=5, live="yes") as reader:
            assert reader.live and reader.info.live
            for _ in reader:
                got += 1
                time.sleep(0.05)     # a consumer far slower than the decoder
        dropped = reader.dropped_frames
    print(f"--live yes: {got} frames handed over, {dropped} dropped")
    assert dropped > 0 and got + dropped == 250


def test_live_yes_in_track_reports_live(served_clip, tmp_path):
    with serve(served_clip.parent) as base:
        summary = _track(f"{base}/{served_clip.name}", tmp_path, "--live", "yes")
    print(f"track --live yes: {summary['frames']} frames, {summary['dropped_frames']} dropped")
    assert summary["live"] is True and summary["complete"] is True
    assert summary["frames"] + summary["dropped_frames"] == 250


def test_live_no_reads_every_frame_of_a_live_only_camera(mjpeg_camera, clip_jpegs, tmp_path):
    """An MJPEG camera has no length (auto: live); with --live no each frame it sends is
    handed over in order at the reader's pace (the server waits on the socket), none
    dropped."""
    camera = mjpeg_camera(clip_jpegs[:120], fps=None)
    with VideoReader(camera.url, reconnect_seconds=5) as reader:
        assert reader.live
    camera = mjpeg_camera(clip_jpegs[:120], fps=None)
    summary = _track(camera.url, tmp_path, "--live", "no", "--max-frames", "100")
    assert summary["live"] is False and summary["dropped_frames"] == 0
    assert summary["frames"] == 100 and summary["complete"] is True


def test_connection_lost_before_the_end_of_a_known_length_is_an_error(served_clip, tmp_path,
                                                                     capfd):
    """A server that stops answering half-way: exit 2, not a complete run of half a video."""
    cut = tmp_path / "cut"
    cut.mkdir()
    data = served_clip.read_bytes()

    class Truncating(RangeHandler):
        def copyfile(self, source, outputfile):   # noqa: D102 - send the head only
            left = getattr(self, "range_left", None) or len(data)
            outputfile.write(source.read(min(left, len(data) // 2)))

    with serve(served_clip.parent, Truncating) as base:
        url = f"{base}/{served_clip.name}"
        code = main(["track", url, "--out", str(cut), "--quiet", "--reconnect-seconds", "1"])
    err = capfd.readouterr().err.splitlines()
    print(err)
    if code == 0:   # the index is at the end: FFmpeg may not open a cut file at all
        pytest.fail(f"a cut-off http video ran to completion: {err}")
    assert code == 2 and len(err) == 1 and err[0].startswith(f"error: {url}: ")


def test_bad_live_value_is_a_usage_error(capfd):
    assert main(["track", "x.avi", "--live", "maybe"]) == 2
    err = capfd.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "--live" in err[0]
    assert os.path.exists("x.avi") is False
