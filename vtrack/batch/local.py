"""The local engine: a pool of worker processes, one video at a time each.

Own pool rather than concurrent.futures, for control over interruption and crashes:
- workers are started with "spawn" (no fork of a parent that may hold threads) and with
  SIGINT ignored (inherited through exec): a terminal's Ctrl-C reaches the parent, which
  forwards SIGTERM; a worker's first SIGTERM raises KeyboardInterrupt in it (so
  `track_video` flushes "complete": false), later ones are swallowed so that flush is not
  cut short;
- on Linux a worker gets SIGTERM when the batch process dies (PR_SET_PDEATHSIG), so even a
  killed parent leaves no worker running;
- a worker that dies (a decoder crash, the OOM killer) fails only its video; a fresh worker
  takes its place;
- on an interruption of the batch, every worker is signalled, given `GRACE_S` to flush (a
  second interruption cuts that short), then killed; results that arrive meanwhile are kept.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from multiprocessing.connection import wait

from vtrack.batch.task import VideoTask, process_video, row

GRACE_S = 20.0
_SIGNALS = (signal.SIGINT, signal.SIGTERM)


# ----------------------------------------------------------------------------- worker side
_interrupted = False


def _on_signal(signum: int, frame: object) -> None:
    # Later signals are swallowed here rather than by SIG_IGN: one already pending when the
    # disposition changed would make CPython print "Signal 15 ignored due to race condition".
    global _interrupted
    if not _interrupted:
        _interrupted = True
        raise KeyboardInterrupt


def _die_with_parent() -> None:
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(Exception):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM, 0, 0, 0)   # PR_SET_PDEATHSIG


def _worker_main(conn, parent_pid: int) -> None:
    """Loop: receive a VideoTask, send back its row; None or SIGTERM ends the loop.

    SIGINT is ignored (inherited from the start): the parent turns a Ctrl-C into SIGTERM.
    Exit code 0 after None, 130 after an interruption (the parent reports the video).
    """
    try:
        signal.signal(signal.SIGTERM, _on_signal)
        _die_with_parent()
        if os.getppid() != parent_pid:
            return
        while True:
            task = conn.recv()
            if task is None:
                return
            result = process_video(task)
            conn.send(result)
            if result["status"] == "interrupted":
                os._exit(130)
    except KeyboardInterrupt:
        os._exit(130)
    except (EOFError, OSError):
        return
    except BaseException:  # noqa: BLE001 - a worker must never print a traceback
        os._exit(70)


# ----------------------------------------------------------------------------- parent side
class _Worker:
    def __init__(self, ctx: mp.context.BaseContext, slot: int) -> None:
        parent_conn, child_conn = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(child_conn, os.getpid()),
                                name=f"vtrack-batch-{slot}", daemon=True)
        with children_ignore_sigint():
            self.proc.start()
        child_conn.close()
        self.conn = parent_conn
        self.task: VideoTask | None = None

    def send(self, task: VideoTask) -> None:
        self.task = task
        self.conn.send(task)

    def result(self) -> dict | None:
        """The finished task's row, or None if the worker died without sending one."""
        try:
            if self.conn.poll():
                return self.conn.recv()
        except (EOFError, OSError):
            pass
        return None

    def signal(self, signum: int) -> None:
        with contextlib.suppress(ProcessLookupError, TypeError):
            if self.proc.is_alive():
                os.kill(self.proc.pid, signum)

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.conn.close()


@contextlib.contextmanager
def children_ignore_sigint():
    """SIGINT ignored while worker processes are started: the disposition survives exec, so
    workers never see a terminal's Ctrl-C (only the batch process does; it stops them in
    order). The local pool forwards SIGTERM; Dask workers would otherwise die of it with
    tracebacks and take their running tasks along. A Ctrl-C during the start-up window is
    lost; the next one works."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _died(task: VideoTask, proc: mp.process.BaseProcess) -> dict:
    proc.join(timeout=1.0)
    code = proc.exitcode
    if code == 130:
        how = "interrupted"
    elif code is not None and code < 0:
        how = f"killed by signal {-code}"
    else:
        how = f"exit code {code}"
    return row(task, "failed", error=f"{task.video}: worker process died ({how})")


def run_local(tasks: list[VideoTask], workers: int,
              on_result: Callable[[dict], None]) -> None:
    """Run `tasks` on `workers` processes; `on_result(row)` as each finishes (parent thread).

    KeyboardInterrupt: workers are interrupted and reaped, then it is re-raised.
    """
    if not tasks:
        return
    ctx = mp.get_context("spawn")
    pending = deque(tasks)
    pool: list[_Worker] = []
    try:
        for slot in range(min(workers, len(tasks))):
            pool.append(_Worker(ctx, slot))
        while True:
            for w in pool:
                if w.task is None and pending:
                    w.send(pending.popleft())
            busy = [w for w in pool if w.task is not None]
            if not busy:
                break
            ready = set(wait([w.conn for w in busy] + [w.proc.sentinel for w in busy]))
            for i, w in enumerate(pool):
                if w.task is None or (w.conn not in ready and w.proc.sentinel not in ready):
                    continue
                result = w.result()
                if result is None:                 # crashed: fail its video, replace it
                    result = _died(w.task, w.proc)
                    w.close()
                    w.task = None
                    if pending:
                        pool[i] = _Worker(ctx, i)
                else:
                    w.task = None
                on_result(result)
    except KeyboardInterrupt:
        _interrupt(pool, on_result)
        raise
    finally:
        _reap(pool)


def _interrupt(pool: list[_Worker], on_result: Callable[[dict], None]) -> None:
    """Signal every worker, collect what they still report, kill any that do not stop."""
    hurry = threading.Event()
    main = threading.current_thread() is threading.main_thread()
    saved = {}
    if main:
        for s in _SIGNALS:
            saved[s] = signal.signal(s, lambda *_: hurry.set())
    try:
        for w in pool:
            w.signal(signal.SIGTERM)
        deadline = time.monotonic() + GRACE_S

        def drain() -> None:           # a video that finished meanwhile still counts
            for w in pool:
                if w.task is not None:
                    result = w.result()
                    if result is not None:
                        w.task = None
                        if result["status"] in ("ok", "failed"):
                            on_result(result)

        while not hurry.is_set():
            drain()
            live = [w for w in pool if w.proc.is_alive()]
            if not live or time.monotonic() >= deadline:
                break
            wait([w.proc.sentinel for w in live], timeout=0.1)
        drain()
    finally:
        if main:
            for s, h in saved.items():
                signal.signal(s, h)


def resource_tracker_running() -> bool:
    """Whether multiprocessing's resource-tracker process is running in this process."""
    with contextlib.suppress(Exception):
        from multiprocessing import resource_tracker

        return getattr(resource_tracker._resource_tracker, "_fd", None) is not None
    return True   # unknown: treat as someone else's


def stop_resource_tracker() -> None:
    """Stop (and reap) multiprocessing's resource-tracker process.

    It would exit by itself once the batch process is gone, but as an orphan; the command
    line calls this at the end, only if the batch started the tracker (it waits until every
    process that inherited the tracker's pipe has exited: ours have by then).
    """
    with contextlib.suppress(Exception):
        from multiprocessing import resource_tracker

        rt = resource_tracker._resource_tracker
        with rt._lock:
            fd, pid = rt._fd, rt._pid
            if fd is None or pid is None:
                return
            rt._fd = rt._pid = None
            os.close(fd)              # the tracker exits once no process holds its pipe
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            if os.waitpid(pid, os.WNOHANG)[0]:
                return
            time.sleep(0.01)
        # still held by someone else's process: leave it to exit on its own


def _reap(pool: list[_Worker]) -> None:
    """Stop idle workers politely, then make sure no worker process outlives the batch."""
    for w in pool:
        if w.proc.is_alive() and w.task is None:
            with contextlib.suppress(Exception):
                w.conn.send(None)
    deadline = time.monotonic() + 5.0
    for w in pool:
        w.proc.join(timeout=max(0.0, deadline - time.monotonic()))
        if w.proc.is_alive():
            w.proc.kill()
            w.proc.join(timeout=5.0)
        w.close()
