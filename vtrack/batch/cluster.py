"""Cluster engines: Ray and Dask distributed run the same task function (`process_video`).

With an address they connect to an existing cluster (every worker must see the videos and
the output folder under the same absolute paths, e.g. a shared file system, and have vtrack
installed); without one they start a local cluster of `workers` single-threaded worker
processes and shut it down afterwards. Each task runs with OpenCV on one thread (a cluster
runs one task per core).

Interruption: queued tasks are cancelled and running ones get a KeyboardInterrupt
(`ray.cancel`; on Dask `interrupt_batch` run on every worker), so each in-progress video
flushes its files with "complete": false; results are collected for up to `GRACE_S`, then
the client disconnects and a local cluster is shut down.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import time
import warnings
from collections.abc import Callable

from vtrack.batch.local import children_ignore_sigint
from vtrack.batch.task import VideoTask, interrupt_batch, process_video, row
from vtrack.errors import InputError, MissingExtraError

GRACE_S = 20.0


def require(engine: str) -> None:
    """Raise MissingExtraError unless the engine's packages are importable."""
    import importlib.util

    if engine == "ray" and importlib.util.find_spec("ray") is None:
        raise MissingExtraError("ray", "ray")
    if engine == "dask" and (importlib.util.find_spec("dask") is None
                             or importlib.util.find_spec("distributed") is None):
        raise MissingExtraError("dask", "dask distributed")


def check_reachable(address: str, timeout: float = 5.0) -> None:
    """InputError unless HOST:PORT (optionally with a scheme) accepts a TCP connection.

    Ray's own connect would otherwise retry for many minutes, logging to stderr.
    """
    import socket

    text = address.strip()
    if "://" in text:
        text = text.split("://", 1)[1]
    text = text.split("/", 1)[0]
    host, sep, port = text.rpartition(":")
    if not sep:
        return   # e.g. Ray's "auto": let the engine resolve it
    try:
        port_no = int(port)
    except ValueError:
        raise InputError(f"--address {address}: expected HOST:PORT") from None
    try:
        with socket.create_connection((host.strip("[]") or "127.0.0.1", port_no), timeout):
            pass
    except OSError as exc:
        raise InputError(f"--address {address}: cannot reach the cluster "
                         f"({exc.strerror or exc})") from None


def _failed(task: VideoTask, exc: BaseException) -> dict:
    text = str(exc).strip().splitlines()
    detail = text[0] if text else ""
    return row(task, "failed", error=f"{task.video}: {type(exc).__name__}: {detail}")


@contextlib.contextmanager
def _keep_sigterm_handler():
    """Put back the SIGTERM handler that was active before (vtrack's: KeyboardInterrupt)."""
    main = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGTERM) if main else None
    try:
        yield
    finally:
        if main and previous is not None:
            signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def _quiet_logs(*names: str):
    """Keep the engines' own INFO/WARNING chatter off stderr (only our lines go there)."""
    saved = {}
    for name in names:
        lg = logging.getLogger(name)
        saved[name] = lg.level
        lg.setLevel(logging.CRITICAL)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        for name, level in saved.items():
            logging.getLogger(name).setLevel(level)


# ------------------------------------------------------------------------------------ ray
def run_ray(tasks: list[VideoTask], workers: int, address: str | None,
            on_result: Callable[[dict], None]) -> None:
    require("ray")
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    with _quiet_logs("ray"):
        import ray
        import ray.exceptions

        started = not ray.is_initialized()   # else: a caller's session, left as it is
        try:
            if started:
                kw = dict(logging_level=logging.ERROR, log_to_driver=False)
                try:
                    with _keep_sigterm_handler():   # ray.init installs its own (exit 1)
                        if address:
                            ray.init(address=address, **kw)
                        else:
                            ray.init(num_cpus=workers, include_dashboard=False, **kw)
                except Exception as exc:  # noqa: BLE001 - a start/connect failure
                    where = f"--address {address}" if address else "local Ray cluster"
                    msg = " ".join(str(exc).split()) or type(exc).__name__
                    raise InputError(f"{where}: cannot start/connect Ray ({msg})") from None
            remote = ray.remote(num_cpus=1, max_retries=0)(process_video)
            refs = {remote.remote(t): t for t in tasks}
            pending = list(refs)
            try:
                while pending:
                    done, pending = ray.wait(pending, num_returns=1)
                    for ref in done:
                        on_result(_ray_result(ray, ref, refs[ref]))
            except KeyboardInterrupt:
                for ref in pending:
                    with contextlib.suppress(Exception):
                        ray.cancel(ref, force=False)
                deadline = time.monotonic() + GRACE_S
                while pending and time.monotonic() < deadline:
                    done, pending = ray.wait(pending, num_returns=1,
                                             timeout=max(0.0, deadline - time.monotonic()))
                    for ref in done:
                        result = _ray_result(ray, ref, refs[ref])
                        if result["status"] == "ok":
                            on_result(result)
                raise
        finally:
            if started:
                with contextlib.suppress(Exception), _keep_sigterm_handler():
                    ray.shutdown()


def _ray_result(ray, ref, task: VideoTask) -> dict:
    try:
        return ray.get(ref)
    except ray.exceptions.TaskCancelledError:
        return row(task, "interrupted")
    except Exception as exc:  # noqa: BLE001 - e.g. WorkerCrashedError: fail this video only
        return _failed(task, exc)


# ----------------------------------------------------------------------------------- dask
def run_dask(tasks: list[VideoTask], workers: int, address: str | None,
             on_result: Callable[[dict], None]) -> None:
    require("dask")
    with _quiet_logs("distributed", "dask", "tornado", "asyncio"):
        import dask
        from distributed import Client, LocalCluster, as_completed
        from distributed import wait as dwait

        cluster = None
        try:
            if address:
                client = Client(address, timeout="20s")
            else:
                with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
                        children_ignore_sigint():
                    cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                           processes=True, dashboard_address=None,
                                           silence_logs=logging.CRITICAL)
                client = Client(cluster)
        except Exception as exc:  # noqa: BLE001
            if cluster is not None:
                with contextlib.suppress(Exception):
                    cluster.close()
            where = f"--address {address}" if address else "local Dask cluster"
            msg = " ".join(str(exc).split()) or type(exc).__name__
            raise InputError(f"{where}: cannot start/connect Dask ({msg})") from None
        try:
            batch_id = tasks[0].batch_id if tasks else ""
            futures = client.map(process_video, tasks, pure=False, retries=0,
                                 key=[f"vtrack-batch-{t.batch_id}-{t.index}" for t in tasks])
            by_key = {f.key: t for f, t in zip(futures, tasks)}
            try:
                for fut in as_completed(futures):
                    on_result(_dask_result(fut, by_key[fut.key]))
            except KeyboardInterrupt:
                with contextlib.suppress(Exception):
                    client.run(interrupt_batch, batch_id)
                left = [f for f in futures if not f.done()]
                with contextlib.suppress(Exception):
                    dwait(left, timeout=GRACE_S)
                for fut in left:
                    if fut.done():
                        result = _dask_result(fut, by_key[fut.key])
                        if result["status"] == "ok":
                            on_result(result)
                with contextlib.suppress(Exception):
                    client.cancel(futures)
                raise
        finally:
            with contextlib.suppress(Exception):
                client.close()
            if cluster is not None:
                with contextlib.suppress(Exception):
                    cluster.close()


def _dask_result(fut, task: VideoTask) -> dict:
    try:
        return fut.result()
    except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker: fail this video only
        return _failed(task, exc)
