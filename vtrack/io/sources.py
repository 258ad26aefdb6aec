"""What `vtrack track SOURCE` reads: a video file, a stream address or a camera (INTERFACE.md).

- `rtsp://...`, `http://...`, `https://...` (scheme in any case): a stream, kept exactly as
  given (never turned into a path);
- `cam:N`: camera index N (OpenCV's device numbering, e.g. /dev/videoN);
- anything else: a path to a video file.

How a source is read is `--live auto|yes|no` (`live_request`): live means newest-frame
reading (frames dropped when processing falls behind, counted) with reconnection when the
connection drops; otherwise every frame is read at the tracker's pace, as from a file.
`auto` reads `rtsp://` and cameras live, files not, and an `http(s)://` source live only
when it has no known length (the decoder decides once it has opened it).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

from vtrack.errors import InputError

STREAM_SCHEMES = ("rtsp", "http", "https")
LIVE_MODES = ("auto", "yes", "no")
_STREAM = re.compile(rf"^({'|'.join(STREAM_SCHEMES)})://", re.IGNORECASE)
_CAMERA = re.compile(r"^cam:(.*)$")


@dataclass(frozen=True)
class Source:
    """A parsed SOURCE argument."""

    spec: str    # exactly as given: what error lines and summary.json show
    kind: str    # "file" | "stream" | "camera"

    @property
    def is_file(self) -> bool:
        """Whether SOURCE is a path on this machine (not a stream address or a camera)."""
        return self.kind == "file"

    @property
    def target(self) -> str | int:
        """What OpenCV opens: the path or address as given, or the camera index."""
        return int(self.spec[4:]) if self.kind == "camera" else self.spec

    @property
    def stem(self) -> str:
        """A file-system-safe name for the default output folder `runs/<stem>/`."""
        if self.kind == "file":
            return Path(self.spec).stem
        if self.kind == "camera":
            return f"cam{self.target}"
        rest = _STREAM.sub("", self.spec).split("?")[0].split("#")[0]
        rest = rest.rsplit("@", 1)[-1]                     # no credentials in folder names
        name = re.sub(r"[^A-Za-z0-9._-]+", "_", rest).strip("._-")
        return name or "stream"


def parse_source(text: str | os.PathLike) -> Source:
    """Classify SOURCE; raises InputError for a malformed `cam:` index."""
    spec = os.fspath(text)
    if _STREAM.match(spec):
        return Source(spec, "stream")
    cam = _CAMERA.match(spec)
    if cam and not Path(spec).exists():
        if not cam.group(1).isdigit():
            raise InputError(f"{spec}: expected cam:N with N a camera index (0, 1, ...)")
        return Source(f"cam:{int(cam.group(1))}", "camera")
    return Source(spec, "file")


def live_request(source: Source, mode: str) -> bool | None:
    """How `--live MODE` reads `source`: True (live), False (every frame, at the caller's
    pace) or None (`auto` on an http(s) stream: live unless the opened stream reports a
    known length, i.e. a frame count or a duration)."""
    if mode not in LIVE_MODES:
        raise ValueError(f"live mode must be one of {', '.join(LIVE_MODES)} (got {mode!r})")
    if mode != "auto":
        return mode == "yes"
    if source.kind == "stream" and source.spec.lower().startswith(("http://", "https://")):
        return None
    return not source.is_file
