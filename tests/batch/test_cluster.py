"""vtrack batch on Ray and Dask: a local 2-worker cluster started by the test (--address),
and the cluster the batch starts itself (no --address). Skipped without the extras.

Start-up dominates: a local Ray cluster takes ~4-12 s to start on a 2-core machine, Dask's
~1-4 s. The test-started clusters live for the module; the test where the batch starts its
own Ray cluster runs first, so two Ray clusters never run at once.
"""

from __future__ import annotations

import csv
import logging
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from vtrack.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _inputs(tmp_path: Path, clip_factory) -> list[str]:
    for k in range(3):
        dst = tmp_path / "in" / f"cam{k}" / "clip.avi"       # colliding stems on purpose
        dst.parent.mkdir(parents=True)
        shutil.copyfile(clip_factory(40, 20 + k), dst)
    (tmp_path / "in" / "broken.mp4").write_bytes(os.urandom(2048))
    return [str(tmp_path / "in")]


def _check(tmp_path: Path, out: Path, clip_factory) -> None:
    with open(out / "batch.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(Path(r["out"]).name, r["status"]) for r in rows] == [
        ("broken", "failed"), ("cam0_clip", "ok"), ("cam1_clip", "ok"), ("cam2_clip", "ok")]
    assert "broken.mp4" in rows[0]["error"]
    assert all(r["frames"] == "40" for r in rows[1:])
    # same bytes as `vtrack track` on the same video
    ref = tmp_path / "ref"
    assert main(["track", str(tmp_path / "in" / "cam1" / "clip.avi"), "--out", str(ref),
                 "--quiet"]) == 0
    assert (ref / "tracks.csv").read_bytes() == (out / "cam1_clip" / "tracks.csv").read_bytes()


def _run_cli(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT))
    return subprocess.run([sys.executable, "-m", "vtrack", "batch", *args], env=env,
                          capture_output=True, text=True, timeout=300)


# ------------------------------------------------------------------------------------ ray
@pytest.mark.slow
def test_ray_starts_and_stops_its_own_cluster(tmp_path, clip_factory):
    pytest.importorskip("ray")
    inputs = _inputs(tmp_path, clip_factory)
    out = tmp_path / "out"
    res = _run_cli(*inputs, "--out", str(out), "--engine", "ray", "--workers", "2", "--quiet")
    assert res.returncode == 2, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr
    _check(tmp_path, out, clip_factory)


@pytest.fixture(scope="module")
def ray_address():
    ray = pytest.importorskip("ray")
    if ray.is_initialized():
        pytest.skip("ray already initialised in this process")
    ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.ERROR,
             log_to_driver=False)
    try:
        yield ray.get_runtime_context().gcs_address
    finally:
        ray.shutdown()


def test_ray_on_an_existing_two_worker_cluster(ray_address, tmp_path, clip_factory):
    inputs = _inputs(tmp_path, clip_factory)
    out = tmp_path / "out"
    res = _run_cli(*inputs, "--out", str(out), "--engine", "ray", "--address", ray_address,
                   "--quiet")
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: 1 of 4 videos failed"), res.stderr
    _check(tmp_path, out, clip_factory)


# ----------------------------------------------------------------------------------- dask
@pytest.fixture(scope="module")
def dask_address():
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=logging.ERROR)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


def test_dask_on_an_existing_two_worker_cluster(dask_address, tmp_path, clip_factory, capsys):
    inputs = _inputs(tmp_path, clip_factory)
    out = tmp_path / "out"
    assert main(["batch", *inputs, "--out", str(out), "--engine", "dask", "--address",
                 dask_address, "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: 1 of 4 videos failed"), lines
    _check(tmp_path, out, clip_factory)


def test_dask_starts_and_stops_its_own_cluster(tmp_path, clip_factory):
    pytest.importorskip("distributed")
    inputs = _inputs(tmp_path, clip_factory)
    out = tmp_path / "out"
    res = _run_cli(*inputs, "--out", str(out), "--engine", "dask", "--workers", "2", "--quiet")
    assert res.returncode == 2, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr
    _check(tmp_path, out, clip_factory)


@pytest.mark.parametrize("engine,module", [("ray", "ray"), ("dask", "distributed")])
def test_unreachable_address_fails_fast_and_writes_nothing(tmp_path, clip_factory, capsys,
                                                           engine, module):
    pytest.importorskip(module)
    inputs = _inputs(tmp_path, clip_factory)
    assert main(["batch", *inputs, "--out", str(tmp_path / "out"), "--engine", engine,
                 "--address", "127.0.0.1:1", "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "cannot reach the cluster" in lines[0], lines
    assert not (tmp_path / "out").exists()
