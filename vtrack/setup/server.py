"""The set-up page's server: stdlib http.server, threaded, on 127.0.0.1 only.

    GET  /             the page (vtrack.setup.page, self-contained)
    GET  /frame.jpg    the video's first frame (JPEG of the decoded frame)
    GET  /api/drawing  the drawing of the config as loaded (config_io)
    POST /api/fit      {"points": [...]} -> the calibration's fit (`fit_points`)
    POST /api/save     a drawing -> {"ok": true, "written": [...], "fit": ...} or
                       {"ok": false, "error": "..."} (nothing written)
    POST /api/done     stops the server (`SetupServer.done` is set)
"""

from __future__ import annotations

import json
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np

from vtrack.errors import InputError
from vtrack.setup import config_io
from vtrack.setup.page import PAGE_HTML

MAX_BODY = 1 << 20   # a drawing is a few kB


def fit_points(points: list[dict[str, Any]], width: int, height: int) -> dict[str, Any]:
    """The project's calibration fit (`parse_calibration`) of the points that have road
    metres: {"ok": true, "points": n, "errors": {...}} with the fit's own error measures, or
    {"ok": false, "points": n, "error": why it refuses them}."""
    from vtrack.analytics.calibration import parse_calibration

    placed = [p for p in points if p.get("world") is not None]
    try:
        cal = parse_calibration(config_io.calibration_toml(placed, width, height),
                                "calibration")
    except InputError as exc:
        message = str(exc).removeprefix("calibration: ")
        return {"ok": False, "points": len(placed), "error": message}
    errors = {k: v for k, v in cal.errors().items() if k != "points"}
    return {"ok": True, "points": len(placed), "errors": _plain(errors)}


def _plain(value: Any) -> Any:
    """JSON-ready numbers (NumPy scalars to float, nested dicts kept)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value


class SetupServer(ThreadingHTTPServer):
    """Serves one video's set-up page; `done` is set when the page says done."""

    daemon_threads = True

    def __init__(self, port: int, frame_jpeg: bytes, files: config_io.SetupFiles,
                 drawing: dict[str, Any]) -> None:
        super().__init__(("127.0.0.1", port), _Handler)
        self.frame_jpeg = frame_jpeg
        self.files = files
        self.drawing = drawing
        self.done = threading.Event()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server_address[1]}/"


class _Handler(BaseHTTPRequestHandler):
    server: SetupServer

    def log_message(self, *args: object) -> None:   # no request log on the terminal
        pass

    def _send(self, body: bytes, content_type: str, status: int = HTTPStatus.OK) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _json(self, obj: Any, status: int = HTTPStatus.OK) -> None:
        self._send(json.dumps(obj).encode(), "application/json", status)

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        path = self.path.split("?")[0]
        if path == "/":
            self._send(PAGE_HTML.encode(), "text/html; charset=utf-8")
        elif path == "/frame.jpg":
            self._send(self.server.frame_jpeg, "image/jpeg")
        elif path == "/api/drawing":
            self._json(self.server.drawing)
        else:
            self._json({"error": "not found"}, HTTPStatus.NOT_FOUND)

    def do_POST(self) -> None:  # noqa: N802
        length = int(self.headers.get("Content-Length") or 0)
        if not 0 <= length <= MAX_BODY:
            self._json({"ok": False, "error": "request too large"}, HTTPStatus.BAD_REQUEST)
            return
        try:
            body = json.loads(self.rfile.read(length) or b"{}")
        except ValueError:
            self._json({"ok": False, "error": "malformed JSON"}, HTTPStatus.BAD_REQUEST)
            return
        path = self.path.split("?")[0]
        size = (self.server.drawing["width"], self.server.drawing["height"])
        if path == "/api/fit":
            self._json(fit_points(body.get("points", []), *size))
        elif path == "/api/save":
            self._save(body, size)
        elif path == "/api/done":
            self._json({"ok": True})
            self.server.done.set()
        else:
            self._json({"error": "not found"}, HTTPStatus.NOT_FOUND)

    def _save(self, drawing: dict[str, Any], size: tuple[int, int]) -> None:
        drawing = {**drawing, "width": size[0], "height": size[1]}
        try:
            written = config_io.save_drawing(drawing, self.server.files)
        except (InputError, KeyError, TypeError, ValueError) as exc:
            self._json({"ok": False, "error": " ".join(str(exc).split())})
            return
        fit = fit_points(drawing.get("points", []), *size) if drawing.get("points") else None
        self._json({"ok": True, "written": [str(p) for p in written], "fit": fit})
