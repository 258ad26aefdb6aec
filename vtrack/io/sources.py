"""What `vtrack track SOURCE` reads: a video file, a stream address or a camera (INTERFACE.md).

- `rtsp://...`, `http://...`, `https://...` (scheme in any case): a stream, kept exactly as
  given (never turned into a path);
- `cam:N`: camera index N (OpenCV's device numbering, e.g. /dev/videoN);
- anything else: a path to a video file.

Streams and cameras are live: read as they come (frames dropped when processing falls
behind), reconnected when the connection drops.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

from vtrack.errors import InputError

STREAM_SCHEMES = ("rtsp", "http", "https")
_STREAM = re.compile(rf"^({'|'.join(STREAM_SCHEMES)})://", re.IGNORECASE)
_CAMERA = re.compile(r"^cam:(.*)$")


@dataclass(frozen=True)
class Source:
    """A parsed SOURCE argument."""

    spec: str    # exactly as given: what error lines and summary.json show
    kind: str    # "file" | "stream" | "camera"

    @property
    def live(self) -> bool:
        """Whether frames arrive in real time (a stream or a camera), not from a file."""
        return self.kind != "file"

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
