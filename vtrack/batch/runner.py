"""`run_batch`: inputs -> videos -> skip completed ones -> an engine -> DIR/batch.csv.

batch.csv (INTERFACE.md): header `video,out,status,frames,fps_processed,tracks,error` and
one row per finished video (status ok / failed / skipped), in input order. It is rewritten
atomically each time a video finishes, so an interrupted batch leaves a valid file that
lists what finished (videos that were still running or queued have no row yet).
"""

from __future__ import annotations

import json
import os
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from vtrack.batch.inputs import discover, output_names
from vtrack.batch.task import COLUMNS, VideoTask, row
from vtrack.errors import InputError
from vtrack.fileio import write_csv

ENGINES = ("local", "ray", "dask")


def cpu_count() -> int:
    """Cores this process may use (affinity / container aware where the OS tells)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


@dataclass
class BatchReport:
    rows: list[dict] = field(default_factory=list)   # batch.csv rows, in input order
    csv: Path | None = None
    seconds: float = 0.0

    def count(self, status: str) -> int:
        return sum(r["status"] == status for r in self.rows)

    @property
    def frames(self) -> int:
        return sum(int(r["frames"]) for r in self.rows if r["status"] == "ok")

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.rows if r["status"] == "failed"]


def completed_summary(out_dir: Path) -> dict | None:
    """summary.json of a finished earlier run in `out_dir` (complete: true), else None."""
    try:
        data = json.loads((out_dir / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if isinstance(data, dict) and data.get("complete") is True:
        return data
    return None


class _Table:
    """batch.csv, rewritten atomically as rows arrive; the progress bar follows it."""

    def __init__(self, path: Path, total: int, progress: bool) -> None:
        self.path = path
        self.rows: dict[int, dict] = {}
        self.bar: Any = None
        self.frames = 0
        if progress:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="video", desc="batch", file=sys.stderr,
                            dynamic_ncols=True)

    def add(self, result: dict, flush: bool = True) -> None:
        if result["status"] not in ("ok", "failed", "skipped"):
            return
        self.rows[result["index"]] = result
        if result["status"] == "ok":
            self.frames += int(result["frames"] or 0)
        if flush:
            self.flush()
        if self.bar is not None:
            failed = sum(r["status"] == "failed" for r in self.rows.values())
            self.bar.set_postfix_str(f"frames={self.frames}, failed={failed}", refresh=False)
            self.bar.update(1)

    def flush(self) -> None:
        try:
            write_csv(self.path, ([r[c] for c in COLUMNS] for _, r in sorted(self.rows.items())),
                      header=COLUMNS)
        except OSError as exc:
            raise InputError(f"{self.path}: cannot write ({exc.strerror or exc})") from None

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def run_batch(inputs: list[str], out: str | os.PathLike, cfg: Any = None, *,
              workers: int | None = None, engine: str = "local", address: str | None = None,
              save_frames: bool = False, save_video: bool = False, rerun: bool = False,
              max_frames: int | None = None, progress: bool = False,
              force: bool = False) -> BatchReport:
    """Track every video named by `inputs` into `out/<name>/`; writes out/batch.csv.

    A video whose folder holds a complete summary.json is skipped unless `force`.
    Raises InputError before any work for bad inputs/options/missing extras;
    KeyboardInterrupt after batch.csv has been brought up to date.
    """
    from vtrack.app.config import AppConfig

    started = time.perf_counter()
    if engine not in ENGINES:
        raise InputError(f"--engine {engine!r}: expected one of {', '.join(ENGINES)}")
    if workers is not None and workers < 1:
        raise InputError(f"--workers must be a positive integer (got {workers})")
    if address and engine == "local":
        raise InputError("--address needs --engine ray or --engine dask")
    if max_frames is not None and max_frames < 1:
        raise InputError("--max-frames must be a positive integer")
    if engine != "local":
        from vtrack.batch.cluster import check_reachable, require

        require(engine)
        if address:
            check_reachable(address)
    if rerun:
        import importlib.util

        if importlib.util.find_spec("rerun") is None:
            from vtrack.errors import MissingExtraError

            raise MissingExtraError("rerun", "rerun-sdk")
    cfg = cfg if cfg is not None else AppConfig()
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder")

    videos = discover(list(inputs), exclude=out)
    names = output_names(videos)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{out}: cannot create the output folder ({exc.strerror})") from None

    workers = workers or cpu_count()
    batch_id = uuid.uuid4().hex[:12]
    todo: list[VideoTask] = []
    table = _Table(out / "batch.csv", len(videos), progress)
    try:
        for i, (video, name) in enumerate(zip(videos, names)):
            task = VideoTask(index=i, video=str(video), video_abs=os.path.abspath(video),
                             out=str(out / name), out_abs=os.path.abspath(out / name),
                             cfg=cfg, save_frames=save_frames, save_video=save_video,
                             rerun=rerun, max_frames=max_frames, batch_id=batch_id)
            done = None if force else completed_summary(out / name)
            if done is not None:
                table.add(row(task, "skipped", done), flush=False)
            else:
                todo.append(task)
        table.flush()
        if not todo:
            pass
        elif engine == "local":
            from dataclasses import replace

            from vtrack.batch.local import run_local

            active = max(1, min(workers, len(todo)))
            threads = max(1, cpu_count() // active)
            todo = [replace(t, cv_threads=threads) for t in todo]
            run_local(todo, workers, table.add)
        elif engine == "ray":
            from vtrack.batch.cluster import run_ray

            run_ray(todo, workers, address, table.add)
        else:
            from vtrack.batch.cluster import run_dask

            run_dask(todo, workers, address, table.add)
    finally:
        table.close()
        table.flush()
    return BatchReport(rows=[r for _, r in sorted(table.rows.items())], csv=table.path,
                       seconds=time.perf_counter() - started)
