"""Video output: the annotated video (INTERFACE.md: H.264, yuv420p, index at the front).

`open_video_writer` encodes with the first H.264 encoder that PyAV's FFmpeg opens (libx264
in PyAV's wheels) into an MP4 whose index (`moov`) precedes the media (`mdat`, FFmpeg's
movflags=faststart), so a browser plays it while it downloads. Without an H.264 encoder it
writes MPEG-4 Part 2 (PyAV's mpeg4, or OpenCV's mp4v when PyAV is not installed) and says
why in `warning`.

Frames are placed by their timestamps (pts = t / time_base), so a live run that dropped
frames still plays in real time; a file's frames are n / fps apart.

Every writer writes to a temporary sibling and renames it over `path` on `close` (also on
an exception or interrupt, through the context manager), so `path` is always a finished,
playable video; if no frame was written, nothing is created.
"""

from __future__ import annotations

import os
import tempfile
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np

from vtrack.errors import InputError

H264_ENCODERS = ("libx264", "libopenh264", "h264")  # tried in this order
X264_OPTIONS = {"preset": "superfast", "crf": "23"}  # see README: CPU vs size
MPEG4_BITS_PER_PIXEL = 0.15  # bit rate of the MPEG-4 Part 2 fallback: w * h * fps * this
_NO_BROWSER = "writing MPEG-4 Part 2, which browsers do not play"


class AtomicVideoWriter:
    """Common part: a temporary sibling renamed over `path` on close; frame size checks.

    Subclasses implement `_encode(image, t)` and `_finish()`.
    """

    codec = ""                    # the encoder's name
    warning: str | None = None    # why the video is not H.264, if it is not

    def __init__(self, path: str | os.PathLike, size: tuple[int, int]) -> None:
        self.path = Path(path)
        self.size = (int(size[0]), int(size[1]))  # width, height
        self.frames_written = 0
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.stem}.", suffix=self.path.suffix,
                                   dir=self.path.parent)
        os.close(fd)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 would make the video private
        self._tmp = Path(tmp)
        self._open = True

    def write(self, image: np.ndarray, t: float | None = None) -> None:
        """Append one HxWx3 uint8 BGR frame of the writer's size, shown at time t (s) from
        the start (default: frames_written / fps)."""
        if not self._open:
            raise ValueError(f"{self.path}: writer is closed")
        if image.shape[:2] != self.size[::-1]:
            raise ValueError(f"frame is {image.shape[1]}x{image.shape[0]}, "
                             f"video is {self.size[0]}x{self.size[1]}")
        self._encode(image, t)
        self.frames_written += 1

    def close(self) -> None:
        """Finalize the container and move it into place; safe to call more than once."""
        if not self._open:
            return
        self._open = False
        try:
            self._finish()
        finally:
            if self.frames_written:
                os.replace(self._tmp, self.path)
            else:
                self._tmp.unlink(missing_ok=True)

    def _discard(self) -> None:
        """Give up before the first frame (the encoder could not be opened)."""
        self._open = False
        self._tmp.unlink(missing_ok=True)

    def _encode(self, image: np.ndarray, t: float | None) -> None:
        raise NotImplementedError

    def _finish(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> AtomicVideoWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _time_base(fps: float) -> tuple[Fraction, Fraction]:
    """(frame rate, time base) with every n / rate an integer number of ticks where possible
    and at most 65535 ticks a second (the MPEG-4 Part 2 limit): rate = p/q, base = 1/(k p)."""
    rate = Fraction(fps).limit_denominator(1001)
    ticks = rate.numerator * max(1, 65535 // rate.numerator)
    return rate, Fraction(1, min(ticks, 65535))


class PyAVWriter(AtomicVideoWriter):
    """MP4 through PyAV: `codec` (an H.264 encoder or mpeg4), yuv420p, moov before mdat.

    yuv420p needs even sides: an odd width or height is padded by repeating the last
    column or row.
    """

    def __init__(self, path: str | os.PathLike, fps: float, size: tuple[int, int],
                 codec: str) -> None:
        import av

        super().__init__(path, size)
        self.codec = codec
        self.fps = fps
        rate, self._tb = _time_base(fps)
        self._pad = (self.size[0] % 2, self.size[1] % 2)
        try:
            self._container = av.open(str(self._tmp), "w", format="mp4",
                                      options={"movflags": "+faststart"})
            stream = self._container.add_stream(codec, rate=rate, options=_options(codec))
            stream.width, stream.height = self.size[0] + self._pad[0], self.size[1] + self._pad[1]
            stream.pix_fmt = "yuv420p"
            stream.codec_context.time_base = self._tb
            if codec == "mpeg4":
                stream.bit_rate = int(MPEG4_BITS_PER_PIXEL * stream.width * stream.height * fps)
            self._stream = stream
        except Exception:
            self._discard()
            raise
        self._last_pts = -1

    def _encode(self, image: np.ndarray, t: float | None) -> None:
        import av

        if any(self._pad):
            image = cv2.copyMakeBorder(image, 0, self._pad[1], 0, self._pad[0],
                                       cv2.BORDER_REPLICATE)
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="bgr24")
        t = self.frames_written / self.fps if t is None else t
        self._last_pts = max(round(t / self._tb), self._last_pts + 1)
        frame.pts, frame.time_base = self._last_pts, self._tb
        self._container.mux(self._stream.encode(frame))

    def _finish(self) -> None:
        try:
            if self.frames_written:
                self._container.mux(self._stream.encode(None))  # drain delayed frames
        finally:
            self._container.close()  # writes the trailer; faststart moves moov first


class OpenCVWriter(AtomicVideoWriter):
    """MPEG-4 Part 2 (mp4v) through OpenCV at a constant `fps`: the fallback without PyAV."""

    codec = "mp4v"

    def __init__(self, path: str | os.PathLike, fps: float, size: tuple[int, int]) -> None:
        super().__init__(path, size)
        self._writer = cv2.VideoWriter(str(self._tmp), cv2.VideoWriter_fourcc(*"mp4v"),
                                       fps, self.size)
        if not self._writer.isOpened():
            self._discard()
            raise InputError(f"{self.path}: OpenCV cannot open an mp4v video writer")

    def _encode(self, image: np.ndarray, t: float | None) -> None:
        self._writer.write(image)

    def _finish(self) -> None:
        self._writer.release()


def _options(codec: str) -> dict[str, str]:
    return X264_OPTIONS if codec == "libx264" else {}


def h264_encoder() -> str | None:
    """The first of H264_ENCODERS that PyAV's FFmpeg can open, or None (also without PyAV)."""
    try:
        import av
    except ImportError:
        return None
    for name in H264_ENCODERS:
        try:
            ctx = av.CodecContext.create(name, "w")
            ctx.width, ctx.height, ctx.pix_fmt = 64, 64, "yuv420p"
            ctx.time_base = Fraction(1, 25)
            ctx.open()
        except Exception:  # noqa: BLE001 - unknown here, or needs hardware that is absent
            continue
        return name
    return None


def open_video_writer(path: str | os.PathLike, fps: float, size: tuple[int, int]
                      ) -> AtomicVideoWriter:
    """The best writer available: H.264 through PyAV, else MPEG-4 Part 2 with a `warning`."""
    from vtrack.io.video import guarded_fps

    fps = guarded_fps(fps)
    try:
        import av  # noqa: F401
    except ImportError:
        writer: AtomicVideoWriter = OpenCVWriter(path, fps, size)
        writer.warning = (f"{path}: PyAV is not installed (pip install 'vtrack[video]'): "
                          f"{_NO_BROWSER}")
        return writer
    codec = h264_encoder()
    if codec is not None:
        return PyAVWriter(path, fps, size, codec)
    writer = PyAVWriter(path, fps, size, "mpeg4")
    writer.warning = f"{path}: no H.264 encoder in this PyAV build: {_NO_BROWSER}"
    return writer
