"""vtrack setup VIDEO: draw count lines, gates, zones, the region of interest and calibration
points on the video's first frame in a browser page, and save them to the config."""

from __future__ import annotations

import argparse
import threading
from pathlib import Path

from vtrack.errors import InputError

NAME = "setup"
HELP = ("draw count lines, gates, zones, the region of interest and calibration points on "
        "VIDEO's first frame in a page on 127.0.0.1; Save writes CFG.toml (other keys kept) "
        "and VIDEO_STEM.calibration.toml")


def _port(text: str) -> int:
    if text == "auto":
        return 0
    if not text.isdigit() or not 0 <= int(text) <= 65535:
        raise InputError(f"--port {text!r}: expected a port number 0..65535 or auto")
    return int(text)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("video", metavar="VIDEO", help="video file (or stream address, cam:N)")
    p.add_argument("--config", metavar="CFG.toml",
                   help="config to edit or create (default VIDEO_STEM.toml beside the video)")
    p.add_argument("--port", type=_port, default=0, metavar="P",
                   help="port on 127.0.0.1 (default auto: a free port)")
    p.add_argument("--no-browser", action="store_true",
                   help="only print the page's address (do not open a browser)")


def first_frame_jpeg(video: str) -> tuple[bytes, int, int]:
    """The first decoded frame of VIDEO as JPEG bytes, and its width and height."""
    import cv2

    from vtrack.io.video import VideoReader

    with VideoReader(video, max_frames=1, live="no", reconnect_seconds=10) as reader:
        frame = next(iter(reader), None)
    if frame is None:
        raise InputError(f"{video}: video has no frames")
    ok, data = cv2.imencode(".jpg", frame.image, [cv2.IMWRITE_JPEG_QUALITY, 92])
    if not ok:
        raise InputError(f"{video}: cannot encode the first frame as JPEG")
    return data.tobytes(), frame.image.shape[1], frame.image.shape[0]


def run(args: argparse.Namespace) -> int:
    from vtrack.setup import config_io
    from vtrack.setup.server import SetupServer
    from vtrack.io.sources import parse_source

    source = parse_source(args.video)
    folder = Path(args.video).parent if source.is_file else Path.cwd()
    cfg_path = Path(args.config) if args.config else folder / f"{source.stem}.toml"
    existing = config_io.read_config(cfg_path)
    files = config_io.SetupFiles.beside(cfg_path, source.stem, existing)
    jpeg, width, height = first_frame_jpeg(source.spec)
    drawing = config_io.load_drawing(existing, files, width, height)
    try:
        server = SetupServer(args.port, jpeg, files, drawing)
    except OSError as exc:
        raise InputError(f"--port {args.port}: cannot listen on 127.0.0.1 "
                         f"({exc.strerror or exc})") from None
    thread = threading.Thread(target=server.serve_forever, name="vtrack-setup", daemon=True)
    thread.start()
    try:   # from here on, Ctrl-C (or SIGTERM) ends the session normally
        print(f"vtrack setup: {server.url} (saves {cfg_path}; Done on the page or Ctrl-C "
              f"stops)", flush=True)
        if not args.no_browser:
            import webbrowser

            webbrowser.open(server.url)
        while not server.done.wait(0.2):
            pass
    except KeyboardInterrupt:
        print("stopped")
    finally:
        server.shutdown()
        server.server_close()
    return 0
