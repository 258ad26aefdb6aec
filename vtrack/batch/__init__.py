"""`vtrack batch`: many videos, each tracked into its own folder, on a local process pool
or a Ray / Dask cluster (see runner, inputs, task, local, cluster).

Import-light on purpose: cluster workers import `vtrack.batch.task` to unpickle the task.
"""

from __future__ import annotations

from typing import Any

__all__ = ["run_batch", "BatchReport", "discover", "output_names", "process_video",
           "VideoTask"]


def __getattr__(name: str) -> Any:
    if name in ("run_batch", "BatchReport"):
        from vtrack.batch import runner

        return getattr(runner, name)
    if name in ("discover", "output_names"):
        from vtrack.batch import inputs

        return getattr(inputs, name)
    if name in ("process_video", "VideoTask"):
        from vtrack.batch import task

        return getattr(task, name)
    raise AttributeError(name)
