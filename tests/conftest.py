"""Shared fixtures: synthetic videos (rendered once per session), the real clips and an
in-process CLI runner."""

from __future__ import annotations

import contextlib
import io
import signal
import struct
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_VIDEOS = ROOT.parent / "shared" / "videos"
HIGHWAY = SHARED_VIDEOS / "bgslibrary_video03_highway.avi"
RESIDENTIAL = SHARED_VIDEOS / "vehicle_counting_tf_sub-1504614469486_residential.mp4"


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "golden: compares with the recorded outputs of tests/golden (.ci/run runs "
        "these once more under another OpenBLAS kernel)")


@pytest.fixture(scope="session")
def load_script():
    """Import a developer script of scripts/ by name (e.g. "eval_suite") as a module."""
    import importlib.util
    import sys

    def load(name: str):
        spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod   # dataclasses look their module up there
        spec.loader.exec_module(mod)
        return mod

    return load


@pytest.fixture(scope="session")
def synth_video(tmp_path_factory):
    """Render (once) a synthetic clip per seed; returns a function seed -> folder."""
    from vtrack.sim.traffic import render_scene

    cache: dict[int, Path] = {}

    def make(seed: int, frames: int = 250, vehicles: int = 12) -> Path:
        key = (seed, frames, vehicles)
        if key not in cache:
            out = tmp_path_factory.mktemp(f"synth{seed}")
            render_scene(out, frames=frames, vehicles=vehicles, width=640, height=360, fps=25.0,
                         seed=seed)
            cache[key] = out
        return cache[key]

    return make


@pytest.fixture(scope="session")
def overhead_truth():
    """(seed, folder) -> writes folder/calibration.toml and folder/world.csv for the
    synth_video fixture's scene of that seed: the overhead view is a pure scale (pixels /
    px_per_m, Y from the road's top kerb as in world.csv); world.csv has each vehicle's
    speed, length and class per frame (`vtrack synth` writes the same file)."""
    from vtrack.sim.groundtruth import format_world
    from vtrack.sim.traffic import simulate_traffic, world_rows

    def write(seed: int, folder: Path, frames: int = 250, vehicles: int = 12) -> Path:
        tr = simulate_traffic(frames, vehicles, 640, 360, 25.0, seed)
        ppm, top = tr.layout.px_per_m, tr.layout.road_top
        pts = [(40, 60), (600, 70), (590, 330), (50, 320)]
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "calibration.toml").write_text("frame_size = [640, 360]\n" + "".join(
            f"[[points]]\nimage = [{u}, {v}]\nworld = [{u / ppm:.6f}, {(v - top) / ppm:.6f}]\n"
            for u, v in pts))
        (folder / "world.csv").write_text(format_world(world_rows(tr)))
        return folder / "calibration.toml"

    return write


CLIPS = {"highway": HIGHWAY, "residential": RESIDENTIAL}


@pytest.fixture
def real_clip():
    """name -> path of a real clip in ../shared/videos (the test skips if it is absent)."""

    def get(name: str) -> Path:
        path = CLIPS[name]
        if not path.exists():
            pytest.skip(f"real clip not available: {path}")
        return path

    return get


@pytest.fixture
def cli_stdout():
    """args -> what `vtrack ARGS` prints on stdout, run in-process (it must exit 0)."""
    from vtrack.cli import main

    def run(args: list[str]) -> str:
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(args) == 0
        return buf.getvalue()

    return run


class MjpegCamera:
    """A live camera on a local HTTP server: MJPEG (multipart/x-mixed-replace) frames of a
    clip, looped, on a wall-clock timeline (frame k at start + k / fps, like a camera that
    keeps filming while nobody watches); fps=None sends as fast as the client reads.

    cut_after=N closes the first connection after N frames (a dropped connection);
    down_for=S then answers 503 for S seconds (None: for ever, the camera is gone).
    `sent` counts frames sent; `connections` counts accepted connections.
    """

    def __init__(self, frames: list[bytes], fps: float | None = 25.0,
                 cut_after: int | None = None, down_for: float | None = 1.0) -> None:
        import http.server
        import threading
        import time

        self.frames, self.fps = frames, fps
        self.cut_after, self.down_for = cut_after, down_for
        self.sent = 0
        self.connections = 0
        self.cut_at: float | None = None
        self.start = time.monotonic()
        camera = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 - http.server's name
                camera.serve(self)

            def log_message(self, *args: object) -> None:
                pass

        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/camera.mjpg"
        self._thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self._thread.start()

    def _down(self) -> bool:
        import time

        if self.cut_at is None:
            return False
        return self.down_for is None or time.monotonic() < self.cut_at + self.down_for

    def serve(self, req) -> None:
        import time

        if self._down():
            req.send_error(503)
            return
        self.connections += 1
        first = self.connections == 1
        req.send_response(200)
        req.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
        req.end_headers()
        sent_here = 0
        k = 0
        while True:
            if self.fps is not None:
                k = int((time.monotonic() - self.start) * self.fps)
                time.sleep(max(0.0, self.start + (k + 1) / self.fps - time.monotonic()))
            jpeg = self.frames[k % len(self.frames)]
            k += self.fps is None
            try:
                req.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: "
                                + str(len(jpeg)).encode() + b"\r\n\r\n" + jpeg + b"\r\n")
                req.wfile.flush()
            except OSError:
                return          # the client went away
            self.sent += 1
            sent_here += 1
            if first and self.cut_after is not None and sent_here >= self.cut_after:
                self.cut_at = time.monotonic()
                return          # drop the connection

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


def jpeg_frames(video: Path, limit: int | None = None) -> list[bytes]:
    """The frames of a video file as JPEG images."""
    import cv2

    cap = cv2.VideoCapture(str(video))
    out = []
    while limit is None or len(out) < limit:
        ok, image = cap.read()
        if not ok:
            break
        out.append(cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes())
    cap.release()
    return out


@pytest.fixture
def mjpeg_camera():
    """(frames, **options) -> a started MjpegCamera (see there), stopped after the test."""
    cameras: list[MjpegCamera] = []

    def start(frames: list[bytes], **options) -> MjpegCamera:
        cameras.append(MjpegCamera(frames, **options))
        return cameras[-1]

    yield start
    for camera in cameras:
        camera.close()


def top_level_boxes(path: Path) -> list[str]:
    """Types of the top-level boxes of an MP4 file, in file order (ISO 14496-12 4.2: a
    32-bit size, a 4-character type; size 1 means a 64-bit size follows, 0 to the end)."""
    data = path.read_bytes()
    boxes, i = [], 0
    while i + 8 <= len(data):
        size, kind = struct.unpack(">I4s", data[i:i + 8])
        if size == 1:
            size = struct.unpack(">Q", data[i + 8:i + 16])[0]
        elif size == 0:
            size = len(data) - i
        if size < 8:
            raise ValueError(f"{path}: bad box size {size} at {i}")
        boxes.append(kind.decode("latin-1"))
        i += size
    return boxes


def read_back(path: Path) -> dict:
    """Codec, pixel format, frames, their times and the box order of a written video."""
    import av

    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        times = [float(f.pts * f.time_base) for f in container.decode(stream)]
        ctx = stream.codec_context
        return {"codec": ctx.name, "pix_fmt": ctx.pix_fmt, "size": (ctx.width, ctx.height),
                "frames": len(times), "times": times, "boxes": top_level_boxes(path)}


@pytest.fixture
def read_video():
    """path -> codec, pix_fmt, size, frames, frame times and top-level MP4 boxes, read back
    with PyAV (skips the test without PyAV)."""
    pytest.importorskip("av")
    return read_back


@pytest.fixture(scope="session")
def clip_jpegs(synth_video):
    """The frames of the synthetic clip of seed 0 (640x360, 250 frames) as JPEG images."""
    return jpeg_frames(synth_video(0) / "video.avi")


@pytest.fixture
def terminal_sigint():
    """SIGINT for the processes a test starts as a terminal's foreground job has it. A test
    run started in the background (`cmd &` in a script) inherits SIGINT ignored, and so
    would every vtrack it starts: Unix keeps Ctrl-C away from background jobs, and the
    interrupt tests would see the run finish instead of stopping."""
    previous = signal.getsignal(signal.SIGINT)
    if previous == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)  # children get SIG_DFL
    yield
    signal.signal(signal.SIGINT, previous)
