"""Video input and output.

`VideoReader` decodes in a supervised child process (a fresh `python -c`, so a caller's
script needs no `if __name__ == "__main__"` guard, unlike multiprocessing's spawn) and hands
frames over through a shared-memory ring of `RING_SLOTS` frames:

- a malformed file that makes the native decoder abort kills only the child; the reader
  yields the frames decoded so far, then raises `InputError` (the caller can flush its
  outputs and exit 2);
- decoding overlaps the caller's work (a second core for the pipeline).

The ring is an anonymous memory file (memfd) whose descriptor is passed over the control
socket, so nothing is left behind even if both processes are killed. Measured at 1280x720
(MJPG): the parent spends ~0.4 ms of CPU per frame (one 2.7 MB copy, two small messages)
against ~5 ms to receive it through a pipe and ~3 ms to decode it in-process.

Test hook: the environment variable VTRACK_TEST_DECODER_ABORT_AFTER=N makes the child call
os.abort() after sending N frames (N=0: before the first frame), to exercise that path.
"""

from __future__ import annotations

import contextlib
import math
import mmap
import os
import signal
import socket
import subprocess
import sys
import tempfile
import weakref
from collections.abc import Iterator
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.reduction import recv_handle, send_handle
from pathlib import Path

# FFmpeg's own log lines must not reach stderr; set before cv2 is imported (here and in the
# decoder child, which imports this module first).
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from vtrack.errors import InputError  # noqa: E402

ABORT_HOOK_ENV = "VTRACK_TEST_DECODER_ABORT_AFTER"
DEFAULT_FPS = 25.0      # used when the container reports no usable frame rate
RING_SLOTS = 4          # frames the decoder may run ahead of the caller
STALL_TIMEOUT_S = 60.0  # a decoder silent this long is considered hung


@dataclass(frozen=True)
class VideoInfo:
    """Static properties of a video."""

    path: str
    width: int
    height: int
    fps: float        # container frame rate; DEFAULT_FPS when it reports none
    frame_count: int  # from the container, 0 if unknown (may differ from frames decoded)


@dataclass
class Frame:
    """One decoded frame."""

    index: int         # 1-based: the n-th decoded frame
    time: float        # seconds since the first frame (see FrameClock)
    image: np.ndarray  # HxWx3 uint8 BGR, owned by the caller


def guarded_fps(fps: float) -> float:
    """The container's frame rate if plausible (0 < fps <= 1000), else DEFAULT_FPS."""
    return fps if math.isfinite(fps) and 0 < fps <= 1000 else DEFAULT_FPS


class FrameClock:
    """Frame times from the container's positions (CAP_PROP_POS_MSEC), guarded.

    t_1 = 0 and t_n = t_{n-1} + dt with dt = pos_n - pos_{n-1} when 0.2 T <= dt <= 5 T
    (T = 1 / fps), else dt = T. Only steps are used, so a constant offset (OpenCV reports
    some AVIs two frames ahead) is harmless, and a bogus position (0 after the last frame
    of an AVI, NaN) costs one nominal step instead of a jump.
    """

    def __init__(self, fps: float) -> None:
        self.period = 1.0 / guarded_fps(fps)
        self._pos: float | None = None
        self._time: float | None = None

    def __call__(self, pos_ms: float) -> float:
        pos = pos_ms / 1000.0
        if self._time is None:
            self._time = 0.0
        else:
            dt = pos - self._pos if self._pos is not None else math.nan
            ok = math.isfinite(dt) and 0.2 * self.period <= dt <= 5 * self.period
            self._time += dt if ok else self.period
        self._pos = pos if math.isfinite(pos) else None
        return self._time


def check_file(path: str | os.PathLike) -> Path:
    """Raise InputError unless `path` is an existing, readable, non-empty regular file."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file")
    if p.is_dir():
        raise InputError(f"{p}: is a directory, not a video file")
    if not os.access(p, os.R_OK):
        raise InputError(f"{p}: permission denied")
    if p.stat().st_size == 0:
        raise InputError(f"{p}: empty file (0 bytes)")
    return p


def _as_bgr(image: np.ndarray) -> np.ndarray:
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    return image


def _video_info(path: str, width: int, height: int, fps: float, count: float) -> VideoInfo:
    """VideoInfo from the container's raw CAP_PROP_FPS and CAP_PROP_FRAME_COUNT."""
    return VideoInfo(path, int(width), int(height), guarded_fps(fps),
                     int(count) if math.isfinite(count) and count > 0 else 0)


def probe(path: str | os.PathLike) -> VideoInfo:
    """Open `path` in this process and decode one frame (no child: for trusted quick checks)."""
    p = check_file(path)
    cap = cv2.VideoCapture(str(p))
    try:
        if not cap.isOpened():
            raise InputError(f"{p}: not a readable video (OpenCV could not open it)")
        ok, image = cap.read()
        if not ok or image is None:
            raise InputError(f"{p}: video has no frames")
        return _video_info(str(p), image.shape[1], image.shape[0],
                           cap.get(cv2.CAP_PROP_FPS), cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()


# ----------------------------------------------------------------------------- decoder child

def _decoder_main(fd: int) -> None:
    """Entry point of the child: decode the job received on socket `fd`; quiet on every exit.

    Protocol, parent -> child: (path, max_frames); the ring's descriptor (SCM_RIGHTS); then
    each slot index once the parent has copied that slot. Child -> parent: ("info", w, h,
    fps, count) or ("error", text); then ("frame", slot, pos_ms)* and ("end",) or ("error",
    text). SIGINT/SIGTERM arrive blocked (see VideoReader._start): the parent decides.
    """
    with contextlib.suppress(ImportError, ValueError, OSError):
        import resource
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # an abort leaves no core file
    conn = Connection(fd)
    try:
        path, max_frames = conn.recv()
        _decode(conn, path, max_frames, _abort_hook())
    except (EOFError, OSError):
        pass  # the parent closed the connection or died
    except Exception as exc:  # noqa: BLE001 - report any decoder failure as bad input
        with contextlib.suppress(OSError):
            conn.send(("error", f"decoder failed ({type(exc).__name__}: {exc})"))
    # Every message went out synchronously: skip interpreter teardown (fast, quiet).
    os._exit(0)


def _decode(conn: Connection, path: str, max_frames: int | None,
            abort_after: int | None) -> None:
    cap = cv2.VideoCapture(path)
    if not cap.isOpened():
        conn.send(("error", "not a readable video (OpenCV could not open it)"))
        return
    ok, first = cap.read()
    if not ok or first is None:
        conn.send(("error", "video has no frames"))
        return
    first = _as_bgr(first)
    height, width = first.shape[:2]
    conn.send(("info", width, height, cap.get(cv2.CAP_PROP_FPS),
               cap.get(cv2.CAP_PROP_FRAME_COUNT)))
    ring_fd = recv_handle(conn)
    ring = mmap.mmap(ring_fd, RING_SLOTS * height * width * 3)
    os.close(ring_fd)
    slots = np.frombuffer(ring, np.uint8).reshape(RING_SLOTS, height, width, 3)
    _stream(conn, cap, first, slots, max_frames, abort_after)


def _stream(conn: Connection, cap: cv2.VideoCapture, first: np.ndarray, slots: np.ndarray,
            max_frames: int | None, abort_after: int | None) -> None:
    free = list(range(RING_SLOTS))
    sent = 0
    while max_frames is None or sent < max_frames:
        if sent == abort_after:
            os.abort()
        if not free:
            free.append(conn.recv())
        k = free.pop()
        if sent == 0:
            slots[k] = first
        else:
            ok, image = cap.read(slots[k])
            if not ok or image is None:
                break
            if image.ctypes.data != slots[k].ctypes.data:  # not decoded in place
                _fit(_as_bgr(image), slots[k])
        conn.send(("frame", k, cap.get(cv2.CAP_PROP_POS_MSEC)))
        sent += 1
    conn.send(("end",))


def _abort_hook() -> int | None:
    value = os.environ.get(ABORT_HOOK_ENV, "").strip()
    return int(value) if value else None


def _fit(image: np.ndarray, slot: np.ndarray) -> None:
    """Copy `image` into `slot`, resizing a frame whose size changed mid-stream."""
    if image.shape != slot.shape:
        image = cv2.resize(image, (slot.shape[1], slot.shape[0]), interpolation=cv2.INTER_AREA)
    slot[...] = image


# ----------------------------------------------------------------------------- reader

def _ring_file(size: int) -> int:
    """Descriptor of an anonymous memory file of `size` bytes (memfd, else an unlinked tmp)."""
    if hasattr(os, "memfd_create"):
        fd = os.memfd_create("vtrack-ring", os.MFD_CLOEXEC)
    else:
        fd, name = tempfile.mkstemp(prefix="vtrack-ring.")
        os.unlink(name)
    os.ftruncate(fd, size)
    return fd


class VideoReader:
    """Iterate the frames of a video file, decoded in a supervised child process.

    Use as a context manager (or call `close`): closing stops the child and frees the ring.
    Iterate once. Raises InputError for a missing, unreadable, empty or non-video file, for
    a video without frames, and (after yielding the frames decoded so far) when the decoder
    dies mid-file. A file that merely ends early just ends the iteration (`frames_read`).
    """

    def __init__(self, path: str | os.PathLike, max_frames: int | None = None) -> None:
        self.path = str(path)
        if max_frames is not None and max_frames < 1:
            raise InputError(f"max frames must be >= 1 (got {max_frames})")
        check_file(path)
        self.frames_read = 0
        self._rings: list[mmap.mmap] = []  # 0 or 1 ring, freed by _shutdown
        self._done = False
        self._start()
        try:
            with contextlib.suppress(OSError):  # a child dead at start-up is reported below
                self._conn.send((self.path, max_frames))
            self.info = self._handshake()
            self._clock = FrameClock(self.info.fps)
            self._pending = self._check(self._receive())  # a crash before frame 1 fails here
        except BaseException:
            self.close()
            raise

    @property
    def pid(self) -> int:
        """Process id of the decoder child."""
        return self._proc.pid

    def _start(self) -> None:
        ours, theirs = socket.socketpair()
        code = ("import sys; sys.path.insert(0, sys.argv[1]); "
                "from vtrack.vision.video import _decoder_main; _decoder_main(int(sys.argv[2]))")
        root = str(Path(__file__).resolve().parents[2])
        # The child inherits this signal mask: Ctrl-C / a group SIGTERM reach only the
        # parent, which then shuts the child down (no traceback, no exit-code race).
        old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        try:
            self._proc = subprocess.Popen([sys.executable, "-c", code, root, str(theirs.fileno())],
                                          pass_fds=[theirs.fileno()], stdin=subprocess.DEVNULL)
            self._conn = Connection(ours.detach())
            self._finalizer = weakref.finalize(self, _shutdown, self._conn, self._proc,
                                               self._rings)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
            theirs.close()

    def _handshake(self) -> VideoInfo:
        _, width, height, fps, count = self._check(self._receive())
        size = RING_SLOTS * height * width * 3
        fd = _ring_file(size)
        try:
            self._rings.append(mmap.mmap(fd, size))
            with contextlib.suppress(OSError):  # a dead child is reported by _receive
                send_handle(self._conn, fd, self._proc.pid)
        finally:
            os.close(fd)
        return _video_info(self.path, width, height, fps, count)

    def _receive(self) -> tuple | None:
        """The child's next message, or None if it died."""
        try:
            if not self._conn.poll(STALL_TIMEOUT_S):
                raise InputError(f"{self.path}: decoder stalled (no frame for "
                                 f"{STALL_TIMEOUT_S:.0f} s) after {self.frames_read} frames")
            return self._conn.recv()
        except (EOFError, OSError):
            return None

    def _check(self, msg: tuple | None) -> tuple:
        """Raise InputError for a dead child or an error message; else return `msg`."""
        if msg is None:
            if self.frames_read == 0:
                raise InputError(f"{self.path}: decoder aborted before the first frame")
            raise InputError(f"{self.path}: decoder aborted after {self.frames_read} frames")
        if msg[0] == "error":
            where = f" after {self.frames_read} frames" if self.frames_read else ""
            raise InputError(f"{self.path}: {msg[1]}{where}")
        return msg

    def __iter__(self) -> Iterator[Frame]:
        while not self._done:
            msg = self._pending or self._check(self._receive())
            self._pending = None
            if msg[0] == "end":
                self.close()
                return
            _, slot, pos_ms = msg
            image = self._copy_slot(slot)
            with contextlib.suppress(OSError):  # the child may already have finished
                self._conn.send(slot)
            self.frames_read += 1
            yield Frame(self.frames_read, self._clock(pos_ms), image)

    def _copy_slot(self, slot: int) -> np.ndarray:
        """A copy of one ring slot (the view is temporary, so the ring can always be freed)."""
        shape = (self.info.height, self.info.width, 3)
        size = shape[0] * shape[1] * 3
        return np.frombuffer(self._rings[0], np.uint8, size, slot * size).reshape(shape).copy()

    def close(self) -> None:
        """Stop the child (if running) and free the ring; safe to call more than once."""
        self._done = True
        self._finalizer()

    def __enter__(self) -> VideoReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _shutdown(conn: Connection, proc: subprocess.Popen, rings: list[mmap.mmap]) -> None:
    """Close the socket (the child exits at its next send/receive), reap it, free the ring.

    The child blocks SIGTERM, so a child stuck in the decoder is killed (SIGKILL); it holds
    nothing that needs cleaning up.
    """
    conn.close()
    try:
        proc.wait(timeout=2.0)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    for ring in rings:
        ring.close()
    rings.clear()


# ----------------------------------------------------------------------------- writer

class VideoWriterAtomic:
    """Write an mp4v video to a temporary sibling and rename it over `path` on close.

    `close` (also on an exception or interrupt, via the context manager) finalizes and
    renames what was written, so the file is always a valid video; if no frame was written,
    nothing is created.
    """

    def __init__(self, path: str | os.PathLike, fps: float, size: tuple[int, int]) -> None:
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
        self._writer: cv2.VideoWriter | None = cv2.VideoWriter(
            tmp, cv2.VideoWriter_fourcc(*"mp4v"), guarded_fps(fps), self.size)
        if not self._writer.isOpened():
            self._writer = None
            self._tmp.unlink(missing_ok=True)
            raise InputError(f"{self.path}: OpenCV cannot open an mp4v video writer")

    def write(self, image: np.ndarray) -> None:
        """Append one HxWx3 uint8 BGR frame of the writer's size."""
        if self._writer is None:
            raise ValueError(f"{self.path}: writer is closed")
        if image.shape[:2] != self.size[::-1]:
            raise ValueError(f"frame is {image.shape[1]}x{image.shape[0]}, "
                             f"video is {self.size[0]}x{self.size[1]}")
        self._writer.write(image)
        self.frames_written += 1

    def close(self) -> None:
        """Finalize the container and move it into place; safe to call more than once."""
        if self._writer is None:
            return
        self._writer.release()
        self._writer = None
        if self.frames_written:
            os.replace(self._tmp, self.path)
        else:
            self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> VideoWriterAtomic:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
