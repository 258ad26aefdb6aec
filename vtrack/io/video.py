"""Video input: files, streams and cameras (see `sources`).

`VideoReader` decodes in a supervised child process (a fresh `python -c`, so a caller's
script needs no `if __name__ == "__main__"` guard, unlike multiprocessing's spawn) and hands
frames over through a shared-memory ring of `RING_SLOTS` frames:

- a malformed file that makes the native decoder abort kills only the child; the reader
  yields the frames decoded so far, then raises `InputError` (the caller can flush its
  outputs and exit 2);
- the child's stdout and stderr (file descriptors 1 and 2, so what FFmpeg, OpenCV and
  glibc print too: OpenCV prints FFmpeg's log on stdout) go to a log file, never to the
  terminal; `save_decoder_log` keeps it;
- decoding overlaps the caller's work (a second core for the pipeline).

A file is read frame by frame at the caller's pace (the child waits for a free slot). A
live source cannot wait: the child keeps reading, hands over at most `LIVE_SLOTS` frames at
a time and holds only the newest of the rest, so when the caller falls behind, older frames
are dropped (`dropped_frames`) and latency stays bounded. A live connection that drops or
stalls is reopened with exponential back-off for up to `reconnect_seconds` (also when first
opening it); then the reader raises InputError. Which sources are read live is `live`
(`sources.live_request`): with "auto" an http(s) stream that reports a known length (a
video file on a web server) is read like a file, every frame at the caller's pace, and
one whose connection breaks before its end raises InputError after the frames read.

The ring is an anonymous memory file (memfd) whose descriptor is passed over the control
socket, so nothing is left behind even if both processes are killed. Measured at 1280x720
(MJPG): the parent spends ~0.4 ms of CPU per frame (one 2.7 MB copy, two small messages)
against ~5 ms to receive it through a pipe and ~3 ms to decode it in-process.

Test hook: the environment variable VTRACK_TEST_DECODER_ABORT_AFTER=N makes the child write
a glibc-style line to its stderr and call os.abort() after sending N frames (N=0: before
the first frame), to exercise that path.
"""

from __future__ import annotations

import contextlib
import math
import mmap
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
import weakref
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.reduction import recv_handle, send_handle
from pathlib import Path
from typing import IO

# FFmpeg's own log lines must not reach stderr; set before cv2 is imported (here and in the
# decoder child, which imports this module first; the child's stderr is a log file, so it
# runs with FFmpeg's errors on: see _DECODER_ENV).
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from vtrack.errors import InputError  # noqa: E402
from vtrack.io.sources import Source, live_request, parse_source  # noqa: E402

ABORT_HOOK_ENV = "VTRACK_TEST_DECODER_ABORT_AFTER"
DEFAULT_FPS = 25.0        # used when the container reports no usable frame rate
RING_SLOTS = 4            # frames the decoder may run ahead of the caller (files)
LIVE_SLOTS = 2            # frames handed over at a time from a live source
STALL_TIMEOUT_S = 60.0    # a decoder silent this long (beyond reconnecting) is hung
LIVE_IO_TIMEOUT_S = 5.0   # a live source that neither opens nor sends a frame this long
BACKOFF_FIRST_S = 0.25    # wait before the second attempt to reconnect; doubles each time
BACKOFF_MAX_S = 4.0
MAX_CLOCK_DRIFT_S = 2.0   # stream timestamps further than this from the wall clock: use it
LOG_TAIL_BYTES = 1 << 20  # at most this much of the decoder's log is kept (its end)
# The child's stderr is a log file: let FFmpeg and OpenCV say what went wrong, and make
# glibc write its fatal messages there rather than to the terminal device.
_LOG_TAG = re.compile(r"^\[OPENCV:FFMPEG:\d+\]|^\[\s*\w+:\d+@[\d.]+\]\s*(global\s+\S+\s+)?")
_DECODER_ENV = {"OPENCV_FFMPEG_LOGLEVEL": "16", "OPENCV_LOG_LEVEL": "WARNING",
                "LIBC_FATAL_STDERR_": "1"}


@dataclass(frozen=True)
class VideoInfo:
    """Static properties of a video."""

    path: str         # the source as given: a path, a stream address or cam:N
    width: int
    height: int
    fps: float        # container frame rate; DEFAULT_FPS when it reports none
    frame_count: int  # from the container, 0 if unknown (may differ from frames decoded)
    live: bool = False  # read live (newest frame, drops counted), not every frame


@dataclass
class Frame:
    """One decoded frame."""

    index: int         # 1-based: the frame's number in the source (see VideoReader `keep`)
    time: float        # seconds since the first frame (see FrameClock, LiveClock)
    image: np.ndarray  # HxWx3 uint8 BGR, owned by the caller


def guarded_fps(fps: float) -> float:
    """The container's frame rate if plausible (0 < fps <= 1000), else DEFAULT_FPS."""
    return fps if math.isfinite(fps) and 0 < fps <= 1000 else DEFAULT_FPS


class FrameClock:
    """Frame times of a file from the container's positions (CAP_PROP_POS_MSEC), guarded.

    t_1 = 0 and t_n = t_{n-1} + dt with dt = pos_n - pos_{n-1} when 0.2 T <= dt <= 5 T
    (T = 1 / fps), else dt = T. Only steps are used, so a constant offset (OpenCV reports
    some AVIs two frames ahead) is harmless, and a bogus position (0 after the last frame
    of an AVI, NaN) costs one nominal step instead of a jump. A caller that skips frames
    passes `steps`, the frames since the last call (the first call: the frame's number):
    the bounds and the nominal step scale with it.
    """

    def __init__(self, fps: float) -> None:
        self.period = 1.0 / guarded_fps(fps)
        self._pos: float | None = None
        self._time: float | None = None

    def __call__(self, pos_ms: float, steps: int = 1) -> float:
        pos = pos_ms / 1000.0
        if self._time is None:
            self._time = (steps - 1) * self.period
        else:
            dt = pos - self._pos if self._pos is not None else math.nan
            ok = math.isfinite(dt) and 0.2 * self.period * steps <= dt <= 5 * self.period * steps
            self._time += dt if ok else steps * self.period
        self._pos = pos if math.isfinite(pos) else None
        return self._time


class LiveClock:
    """Frame times of a live source: the stream's timestamps while they keep pace with the
    wall clock, else the wall clock; strictly increasing across reconnections.

    Within one connection, from the frame that anchors it (run time t0, stream position
    p0, wall time w0): t = t0 + (p - p0) while |(p - p0) - (w - w0)| <= MAX_CLOCK_DRIFT_S
    and the stream steps forward; once it does not (a stream without timestamps, whose
    frame numbers FFmpeg turns into times at a guessed rate, drifts away), the frame
    re-anchors the connection on the wall clock: t = t0 + (w - w0) from then on. The first
    frame of a new connection comes (w - w_prev) after the previous frame. Every step is at
    least 0.2 T (T = 1 / fps), as in FrameClock.
    """

    def __init__(self, fps: float) -> None:
        self.min_step = 0.2 / guarded_fps(fps)
        self._t: float | None = None
        self._wall = 0.0
        self._connection = 0
        self._anchor = (0.0, 0.0, 0.0)   # t0, p0, w0
        self._stream = True              # this connection's timestamps are trusted

    def __call__(self, pos_ms: float, wall_s: float, connection: int) -> float:
        pos = pos_ms / 1000.0
        if self._t is None or connection != self._connection:
            t = 0.0 if self._t is None else self._t + max(wall_s - self._wall, self.min_step)
            self._anchor, self._stream = (t, pos, wall_s), math.isfinite(pos)
        else:
            t0, p0, w0 = self._anchor
            t_stream = t0 + (pos - p0)
            if self._stream and not (t_stream > self._t
                                     and abs((pos - p0) - (wall_s - w0)) <= MAX_CLOCK_DRIFT_S):
                self._stream = False
                self._anchor = (self._t, p0, self._wall)   # carry on from the last frame
                t0, _, w0 = self._anchor
            t = t_stream if self._stream else t0 + (wall_s - w0)
            t = max(t, self._t + self.min_step)
        self._t, self._wall, self._connection = t, wall_s, connection
        return t


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


def _frame_count(count: float) -> int:
    """The container's raw CAP_PROP_FRAME_COUNT if plausible, else 0 (unknown: a stream
    reports a negative or huge count)."""
    return int(count) if math.isfinite(count) and 0 < count < 2**53 else 0


def _video_info(path: str, width: int, height: int, fps: float, count: float,
                live: bool = False) -> VideoInfo:
    """VideoInfo from the container's raw CAP_PROP_FPS and CAP_PROP_FRAME_COUNT."""
    return VideoInfo(path, int(width), int(height), guarded_fps(fps), _frame_count(count),
                     live)


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

@dataclass(frozen=True)
class _Job:
    """What the parent asks the child to decode."""

    target: str | int                 # path, address or camera index
    max_frames: int | None
    reconnect_seconds: float | None   # None: a local file (opened without time-outs)
    keep: tuple[int, ...] | None = None   # not live: hand over only these frames (sorted)
    live: bool | None = False         # None: live unless the source reports its length


def _decoder_main(fd: int) -> None:
    """Entry point of the child: decode the job received on socket `fd`; quiet on every exit.

    Protocol, parent -> child: a _Job; the ring's descriptor (SCM_RIGHTS); then each slot
    index once the parent has copied that slot. Child -> parent: ("info", w, h, fps, count,
    live) or ("error", text); then ("frame", slot, pos_ms, wall_s, dropped, reconnects)* and
    ("end",) or ("error", text). SIGINT/SIGTERM arrive blocked (see VideoReader._start):
    the parent decides.
    """
    with contextlib.suppress(ImportError, ValueError, OSError):
        import resource
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # an abort leaves no core file
    _die_with_parent()
    conn = Connection(fd)
    try:
        job = conn.recv()
        _decode(conn, job, _abort_hook())
    except (EOFError, OSError):
        pass  # the parent closed the connection or died
    except Exception as exc:  # noqa: BLE001 - report any decoder failure as bad input
        with contextlib.suppress(OSError):
            conn.send(("error", f"decoder failed ({type(exc).__name__}: {exc})"))
    # Every message went out synchronously: skip interpreter teardown (fast, quiet).
    os._exit(0)


def _die_with_parent() -> None:
    """Linux: the kernel kills this child when the thread that started it dies, even by
    kill -9 (prctl PR_SET_PDEATHSIG; elsewhere the closed socket stops it at its next
    message). A parent already gone is noticed at the first receive."""
    with contextlib.suppress(OSError, AttributeError):
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # 1: PR_SET_PDEATHSIG


def _open_file(path: str) -> tuple[cv2.VideoCapture, np.ndarray | None, str]:
    """Open a file and decode its first frame: (capture, first frame or None, why not)."""
    cap = cv2.VideoCapture(path)
    if not cap.isOpened():
        return cap, None, "not a readable video (OpenCV could not open it)"
    ok, first = cap.read()
    return cap, (_as_bgr(first) if ok and first is not None else None), "video has no frames"


def _open_live(target: str | int, timeout_s: float
               ) -> tuple[cv2.VideoCapture, np.ndarray | None]:
    """Open a stream (FFmpeg, with open and read time-outs) or a camera; first frame."""
    if isinstance(target, int):
        cap = cv2.VideoCapture(target)
    else:
        ms = int(1000 * timeout_s)
        cap = cv2.VideoCapture(target, cv2.CAP_FFMPEG,
                               [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, ms,
                                cv2.CAP_PROP_READ_TIMEOUT_MSEC, int(1000 * LIVE_IO_TIMEOUT_S)])
    ok, first = cap.read() if cap.isOpened() else (False, None)
    if not ok or first is None:
        cap.release()
        return cap, None
    return cap, _as_bgr(first)


def _connect(target: str | int, budget_s: float
             ) -> tuple[cv2.VideoCapture, np.ndarray] | None:
    """Open a live source, retrying with exponential back-off for up to `budget_s` seconds
    (first attempt at once, then after 0.25, 0.5, 1, 2, 4, 4, ... s); None if it never
    delivered a frame."""
    deadline = time.monotonic() + budget_s
    delay = BACKOFF_FIRST_S
    while True:
        remaining = deadline - time.monotonic()
        cap, first = _open_live(target, min(LIVE_IO_TIMEOUT_S, max(remaining, 0.1)))
        if first is not None:
            return cap, first
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return None
        time.sleep(min(delay, remaining))
        delay = min(2 * delay, BACKOFF_MAX_S)


def _decode(conn: Connection, job: _Job, abort_after: int | None) -> None:
    if job.reconnect_seconds is None:
        cap, first, why = _open_file(job.target)
        if first is None:
            conn.send(("error", why))
            return
    else:
        opened = _connect(job.target, job.reconnect_seconds)
        if opened is None:
            what = (f"cannot open camera {job.target}" if isinstance(job.target, int)
                    else "cannot open the stream")
            conn.send(("error", f"{what} (tried for {job.reconnect_seconds:g} s)"))
            return
        cap, first = opened
    height, width = first.shape[:2]
    count = cap.get(cv2.CAP_PROP_FRAME_COUNT)   # OpenCV: nb_frames, else duration x fps
    live = job.live if job.live is not None else _frame_count(count) == 0
    conn.send(("info", width, height, cap.get(cv2.CAP_PROP_FPS), count, live))
    ring_fd = recv_handle(conn)
    ring = mmap.mmap(ring_fd, RING_SLOTS * height * width * 3)
    os.close(ring_fd)
    slots = np.frombuffer(ring, np.uint8).reshape(RING_SLOTS, height, width, 3)
    if live:
        _stream_live(conn, cap, first, slots[:LIVE_SLOTS], job, abort_after)
    else:
        # a stream of known length (a file on a web server) must be read to its end
        expected = _frame_count(count) if job.reconnect_seconds is not None else 0
        _stream_file(conn, cap, first, slots, job.max_frames, abort_after, job.keep,
                     expected)


def _stream_file(conn: Connection, cap: cv2.VideoCapture, first: np.ndarray,
                 slots: np.ndarray, max_frames: int | None, abort_after: int | None,
                 keep: tuple[int, ...] | None = None, expected: int = 0) -> None:
    """Every frame in order, or only the frames numbered in `keep` (the others are decoded
    but neither converted nor handed over); waits for a free slot (the caller sets the
    pace). `expected` > 0: the source's length; ending more than one frame short of it
    (a network connection that broke) is an error, not the end."""
    free = list(range(len(slots)))
    wanted, last = (None, 0) if keep is None else (set(keep), max(keep))
    sent = number = 0   # frames handed over, frames decoded
    while max_frames is None or sent < max_frames:
        number += 1
        if wanted is not None and number not in wanted:
            if number > last:
                break
            if number > 1 and not cap.grab():
                _short(conn, number, expected)
                return
            continue
        if sent == abort_after:
            _abort()
        if not free:
            free.append(conn.recv())
        k = free.pop()
        if number == 1:
            slots[k] = first
        else:
            ok, image = cap.read(slots[k])
            if not ok or image is None:
                _short(conn, number, expected)
                return
            if image.ctypes.data != slots[k].ctypes.data:  # not decoded in place
                _fit(_as_bgr(image), slots[k])
        conn.send(("frame", k, cap.get(cv2.CAP_PROP_POS_MSEC), time.monotonic(), 0, 0))
        sent += 1
    conn.send(("end",))


def _short(conn: Connection, number: int, expected: int) -> None:
    """Frame `number` could not be decoded: the end, unless a source of `expected` frames
    (AVI counts may be one off) broke before it."""
    if expected and number < expected:
        conn.send(("error", f"connection lost before the end ({expected} frames)"))
    else:
        conn.send(("end",))


def _stream_live(conn: Connection, cap: cv2.VideoCapture, first: np.ndarray,
                 slots: np.ndarray, job: _Job, abort_after: int | None) -> None:
    """Read the source as fast as it delivers; hand over the newest frame whenever a slot is
    free, drop the frames it replaced, reconnect when the source stops delivering. A source
    of known length (a video file served over HTTP) ends for good once all of it was read.
    """
    free = list(range(len(slots)))
    held = first.copy()                                   # the newest frame not handed over
    stamp: tuple[float, float] | None = (cap.get(cv2.CAP_PROP_POS_MSEC), time.monotonic())
    sent = dropped = reconnects = 0
    decoded = 1                                           # on this connection
    ended = False
    while (job.max_frames is None or sent < job.max_frames) and not (ended and stamp is None):
        while conn.poll(0):
            free.append(conn.recv())                      # slots the parent has copied
        if stamp is not None and (free or ended):
            if sent == abort_after:
                _abort()
            k = free.pop() if free else conn.recv()       # ended: wait for the last slot
            slots[k] = held
            conn.send(("frame", k, *stamp, dropped, reconnects))
            sent += 1
            stamp = None
            continue
        ok, image = cap.read(held)
        if not ok or image is None:
            length = _frame_count(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            cap.release()
            # all of it (AVI counts may be 1 off), or a local file (`--live yes`)
            if 0 < length <= decoded + 1 or job.reconnect_seconds is None:
                ended = True
                continue
            reopened = _connect(job.target, job.reconnect_seconds)
            if reopened is None:
                conn.send(("error", f"source lost: no reconnection within "
                                    f"{job.reconnect_seconds:g} s"))
                return
            cap, image = reopened
            reconnects += 1
            decoded = 0
        decoded += 1
        if image.ctypes.data != held.ctypes.data:         # not decoded in place
            _fit(_as_bgr(image), held)
        dropped += stamp is not None
        stamp = (cap.get(cv2.CAP_PROP_POS_MSEC), time.monotonic())
    conn.send(("end",))


def _abort() -> None:
    os.write(2, b"malloc_consolidate(): invalid chunk size (test hook)\n")
    os.abort()


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
    """Iterate the frames of a video file, stream or camera, decoded in a supervised child.

    Use as a context manager (or call `close`): closing stops the child and frees the ring.
    Iterate once. Raises InputError for a missing, unreadable, empty or non-video file, for
    a video without frames, for a live source that cannot be opened within
    `reconnect_seconds`, and (after yielding the frames decoded so far) when the decoder
    dies or a live source is lost. A file that merely ends early just ends the iteration
    (`frames_read`). `dropped_frames` and `reconnects` count what a live source lost.
    `keep` (not live): hand over only the frames with these numbers (1-based; the child
    still decodes the others, to stay exact on any codec, but skips their conversion and
    hand-over), each with its number as `index`. `live` is `--live auto|yes|no`
    (`sources.live_request`); `self.live` is what was decided once the source was open.
    """

    def __init__(self, source: str | os.PathLike | Source, max_frames: int | None = None,
                 reconnect_seconds: float = 30.0, keep: Iterable[int] | None = None,
                 live: str = "auto") -> None:
        self.source = source if isinstance(source, Source) else parse_source(source)
        self.path = self.source.spec
        if max_frames is not None and max_frames < 1:
            raise InputError(f"max frames must be >= 1 (got {max_frames})")
        if not (reconnect_seconds >= 0 and math.isfinite(reconnect_seconds)):
            raise InputError(f"reconnect seconds must be >= 0 (got {reconnect_seconds})")
        if self.source.is_file:
            check_file(self.path)
        request = live_request(self.source, live)
        self._keep = None if keep is None else tuple(sorted(set(keep)))
        if self._keep is not None and (request is not False or not self._keep
                                       or self._keep[0] < 1):
            raise ValueError("keep: frame numbers >= 1 of a source not read live")
        self.frames_read = 0
        self.dropped_frames = 0
        self.reconnects = 0
        remote = not self.source.is_file
        self._stall_s = STALL_TIMEOUT_S + (reconnect_seconds + 2 * LIVE_IO_TIMEOUT_S
                                           if remote else 0.0)
        self._rings: list[mmap.mmap] = []  # 0 or 1 ring, freed by _shutdown
        self._log: IO[bytes] = tempfile.TemporaryFile(prefix="vtrack-decoder.")
        self._done = False
        self._start()
        try:
            with contextlib.suppress(OSError):  # a child dead at start-up is reported below
                self._conn.send(_Job(self.source.target, max_frames,
                                     reconnect_seconds if remote else None, self._keep,
                                     request))
            self.info = self._handshake()
            self.live = self.info.live
            self._clock = (LiveClock(self.info.fps) if self.live
                           else FrameClock(self.info.fps))
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
                "from vtrack.io.video import _decoder_main; _decoder_main(int(sys.argv[2]))")
        root = str(Path(__file__).resolve().parents[2])
        # The child inherits this signal mask: Ctrl-C / a group SIGTERM reach only the
        # parent, which then shuts the child down (no traceback, no exit-code race).
        old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        try:
            self._proc = subprocess.Popen([sys.executable, "-c", code, root, str(theirs.fileno())],
                                          pass_fds=[theirs.fileno()], stdin=subprocess.DEVNULL,
                                          stdout=self._log, stderr=self._log,
                                          env={**os.environ, **_DECODER_ENV})
            self._conn = Connection(ours.detach())
            self._finalizer = weakref.finalize(self, _shutdown, self._conn, self._proc,
                                               self._rings)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
            theirs.close()

    def _handshake(self) -> VideoInfo:
        _, width, height, fps, count, live = self._check(self._receive())
        size = RING_SLOTS * height * width * 3
        fd = _ring_file(size)
        try:
            self._rings.append(mmap.mmap(fd, size))
            with contextlib.suppress(OSError):  # a dead child is reported by _receive
                send_handle(self._conn, fd, self._proc.pid)
        finally:
            os.close(fd)
        return _video_info(self.path, width, height, fps, count, live)

    def _receive(self) -> tuple | None:
        """The child's next message, or None if it died."""
        try:
            if not self._conn.poll(self._stall_s):
                raise InputError(f"{self.path}: decoder stalled (no frame for "
                                 f"{self._stall_s:.0f} s) after {self.frames_read} frames")
            return self._conn.recv()
        except (EOFError, OSError):
            return None

    def _check(self, msg: tuple | None) -> tuple:
        """Raise InputError for a dead child or an error message; else return `msg`."""
        if msg is not None and msg[0] != "error":
            return msg
        if msg is None:
            what = "decoder aborted"
            where = f" after {self.frames_read} frames" if self.frames_read else \
                " before the first frame"
        else:
            what = msg[1]
            where = f" after {self.frames_read} frames" if self.frames_read else ""
        if not self.frames_read:  # no output folder holds the log yet: quote its last line
            self.close()
            last = self.last_decoder_message()
            where += f" (decoder said: {last})" if last else ""
        raise InputError(f"{self.path}: {what}{where}")

    def __iter__(self) -> Iterator[Frame]:
        previous = 0   # the number of the last frame handed over
        while not self._done:
            msg = self._pending or self._check(self._receive())
            self._pending = None
            if msg[0] == "end":
                self.close()
                return
            _, slot, pos_ms, wall_s, self.dropped_frames, reconnects = msg
            image = self._copy_slot(slot)
            with contextlib.suppress(OSError):  # the child may already have finished
                self._conn.send(slot)
            self.frames_read += 1
            number = self.frames_read if self._keep is None else self._keep[self.frames_read - 1]
            if self.live:
                self.reconnects = reconnects
                t = self._clock(pos_ms, wall_s, reconnects)
            else:
                t = self._clock(pos_ms, number - previous)
            previous = number
            yield Frame(number, t, image)

    def _copy_slot(self, slot: int) -> np.ndarray:
        """A copy of one ring slot (the view is temporary, so the ring can always be freed)."""
        shape = (self.info.height, self.info.width, 3)
        size = shape[0] * shape[1] * 3
        return np.frombuffer(self._rings[0], np.uint8, size, slot * size).reshape(shape).copy()

    # ------------------------------------------------------------------ decoder's log
    def _log_tail(self) -> bytes:
        self._log.flush()
        size = self._log.seek(0, os.SEEK_END)
        self._log.seek(max(0, size - LOG_TAIL_BYTES))
        return self._log.read()

    def last_decoder_message(self) -> str:
        """The last line the decoder child printed ('' if none), FFmpeg's own preferred
        (OpenCV's warnings about which backend it tried come after it), without the tags
        OpenCV puts in front."""
        lines = [line for line in self._log_tail().decode("utf-8", "replace").split("\n")
                 if line.strip()]
        ffmpeg = [line for line in lines if line.startswith("[OPENCV:FFMPEG:")]
        last = (ffmpeg or lines or [""])[-1]
        return " ".join(_LOG_TAG.sub("", last).split())

    def save_decoder_log(self, path: str | os.PathLike) -> bool:
        """Write what the decoder child said (its last LOG_TAIL_BYTES) to `path` atomically;
        False, and nothing written, if it said nothing."""
        tail = self._log_tail()
        if not tail:
            return False
        from vtrack.fileio import atomic_open

        with atomic_open(path, "wb") as fh:
            fh.write(tail)
        return True

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
