"""The one task function every engine runs: track one video into its folder, return its row.

`process_video` never raises for a bad video: the failure becomes a row with status
"failed" and a one-line error. An interruption (KeyboardInterrupt inside the task: a signal
in a local worker, `ray.cancel`, or `interrupt_batch` on a Dask worker) lets `track_video`
flush its outputs with "complete": false and returns status "interrupted", which never
reaches batch.csv.

Kept light at import time: cluster workers import this module to unpickle the function.
"""

from __future__ import annotations

import ctypes
import json
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

COLUMNS = ["video", "out", "status", "frames", "fps_processed", "tracks", "error"]


@dataclass(frozen=True)
class VideoTask:
    index: int                 # position in the batch (row order of batch.csv)
    video: str                 # path as found (batch.csv's `video`)
    video_abs: str             # absolute path the worker opens
    out: str                   # output folder as named to the user (batch.csv's `out`)
    out_abs: str               # absolute output folder the worker writes
    cfg: Any                   # vtrack.app.config.AppConfig
    save_frames: bool = False
    save_video: bool = False
    rerun: bool = False        # write out/tracks.rrd
    max_frames: int | None = None
    cv_threads: int = 1        # cv2.setNumThreads in the worker (0: leave OpenCV's default)
    batch_id: str = ""


def one_line(text: str) -> str:
    return " ".join(str(text).split())


def row(task: VideoTask, status: str, summary: dict | None = None, error: str = "") -> dict:
    s = summary or {}
    return {"index": task.index, "video": task.video, "out": task.out, "status": status,
            "frames": s.get("frames", ""), "fps_processed": s.get("fps_processed", ""),
            "tracks": s.get("tracks", ""), "error": one_line(error)}


# -------------------------------------------------------------- interrupting cluster tasks
_lock = threading.Lock()
_running: dict[int, str] = {}      # thread ident -> batch id of the task it runs
_cancelled: set[str] = set()       # batch ids interrupted in this process


def interrupt_batch(batch_id: str) -> int:
    """Interrupt this process's running tasks of `batch_id` and cancel its queued ones.

    Raises KeyboardInterrupt asynchronously in each thread running such a task (it lands
    between two Python bytecodes, i.e. within one frame), so `track_video` flushes its
    files with "complete": false. Returns how many tasks were interrupted. Run on every
    Dask worker with `client.run`.
    """
    hit = 0
    with _lock:
        _cancelled.add(batch_id)
        for ident, bid in list(_running.items()):
            if bid == batch_id:
                del _running[ident]   # exactly one interruption per task
                ctypes.pythonapi.PyThreadState_SetAsyncExc(
                    ctypes.c_ulong(ident), ctypes.py_object(KeyboardInterrupt))
                hit += 1
    return hit


# ------------------------------------------------------------------------- the task
def process_video(task: VideoTask) -> dict:
    """Track one video (same outputs as `vtrack track`); returns its batch.csv row."""
    started = time.time()
    try:
        return _process(task)
    except KeyboardInterrupt:
        return _completed(task, started) or row(task, "interrupted")


def _completed(task: VideoTask, started: float) -> dict | None:
    """The "ok" row of a video whose run finished (its summary.json, written by this task,
    says complete) before the interrupt landed, else None: a finished video still counts."""
    path = Path(task.out_abs) / "summary.json"
    try:
        if path.stat().st_mtime < started:
            return None
        summary = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return row(task, "ok", summary) if summary.get("complete") is True else None


def _process(task: VideoTask) -> dict:
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
    if task.cv_threads > 0 and "OPENCV_FOR_THREADS_NUM" not in os.environ:
        # read by OpenCV at import: reaches the decoder child that VideoReader starts
        os.environ["OPENCV_FOR_THREADS_NUM"] = str(task.cv_threads)
    ident = threading.get_ident()
    with _lock:
        if task.batch_id in _cancelled:
            return row(task, "interrupted")
        _running[ident] = task.batch_id
    try:
        from vtrack.errors import InputError
        from vtrack.app.track import TrackOptions, track_video

        opts = TrackOptions(save_frames=task.save_frames, save_video=task.save_video,
                            rerun=str(Path(task.out_abs) / "tracks.rrd") if task.rerun else None,
                            max_frames=task.max_frames, progress=False,
                            cv_threads=task.cv_threads)
        try:
            summary = track_video(task.video_abs, task.out_abs, task.cfg, opts)
        except InputError as exc:
            return row(task, "failed", error=str(exc))
        except Exception as exc:  # noqa: BLE001 - one video's failure must not stop the batch
            return row(task, "failed", error=f"{task.video}: {type(exc).__name__}: {exc}")
        return row(task, "ok", summary)
    finally:
        with _lock:
            if _running.pop(ident, None) is None:
                # interrupt_batch already targeted this thread: drop its exception if it is
                # still pending (the set and this clear both happen under the lock)
                ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(ident), None)
