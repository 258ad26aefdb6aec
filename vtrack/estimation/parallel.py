"""Independent tasks side by side on the machine's cores: the cases of a seed experiment, and
the filters of a case (vtrack/experiments), each a stack of Monte Carlo runs.

The workers are forked processes: they inherit the task as it stands, closures and all, and
only the results travel back (pickled). A task's numbers do not depend on where it runs (a
filter does not depend on what runs beside it), so the results are those of one process.
`VTRACK_WORKERS=1` runs everything in this process; so does a platform without fork, and a
worker (no workers of workers).
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
from collections.abc import Callable, Sequence
from typing import TypeVar

T = TypeVar("T")
R = TypeVar("R")

WORKERS_VARIABLE = "VTRACK_WORKERS"

_TASKS: tuple[Callable, Sequence] | None = None     # what the forked workers run
_PARENT = 0                                         # the process whose workers they are
PR_SET_PDEATHSIG = 1                                # linux/prctl.h


def workers() -> int:
    """How many processes may work at once: VTRACK_WORKERS (an integer >= 1) if set, else
    the CPUs this process may run on; 1 where processes cannot be forked, and in a worker."""
    if "fork" not in multiprocessing.get_all_start_methods() \
            or multiprocessing.current_process().daemon:
        return 1
    value = os.environ.get(WORKERS_VARIABLE, "").strip()
    if value:
        if not value.isdigit() or int(value) < 1:
            raise ValueError(f"{WORKERS_VARIABLE} must be an integer >= 1, not {value!r}")
        return int(value)
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
        else os.cpu_count() or 1


def map_tasks(fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
    """[fn(item) for item in items], the items handed to min(workers(), len(items)) forked
    processes in order as each becomes free (so put the longest first). An exception in a
    task is raised here."""
    n = min(workers(), len(items))
    if n <= 1:
        return [fn(item) for item in items]
    global _TASKS, _PARENT
    _TASKS, _PARENT = (fn, items), os.getpid()
    try:
        with multiprocessing.get_context("fork").Pool(n, initializer=_worker_signals) as pool:
            return pool.map(_run_task, range(len(items)), chunksize=1)
    finally:
        _TASKS = None


def _worker_signals() -> None:
    """A worker leaves Ctrl-C to its parent (which ends the pool) and dies at once on the
    SIGTERM that ends the pool, whatever handler the parent had (the CLI's), and (Linux) with
    its parent: a killed experiment leaves no worker computing for nobody."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):       # no prctl: the worker ends at its next result
        pass
    if os.getppid() != _PARENT:             # the parent died before the prctl
        os._exit(1)


def _run_task(i: int) -> object:
    fn, items = _TASKS
    return fn(items[i])
