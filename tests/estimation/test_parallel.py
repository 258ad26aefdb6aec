"""parallel.map_tasks: independent tasks in forked worker processes, the results of one
process, in order; and the experiments give the same JSON on one worker as on several."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest

from vtrack.estimation import parallel
from vtrack.estimation.parallel import map_tasks, workers
from vtrack.experiments import load_all

forks = pytest.mark.skipif(not hasattr(os, "fork"), reason="worker processes need fork")


@forks
def test_tasks_run_in_workers_in_order(monkeypatch):
    """A closure over local state (nothing picklable about it) runs in forked workers; the
    results come back in the order of the items."""
    monkeypatch.setenv(parallel.WORKERS_VARIABLE, "2")
    offset = {"value": 10}
    out = map_tasks(lambda i: (i + offset["value"], os.getpid()), list(range(6)))
    assert [v for v, _ in out] == list(range(10, 16))
    assert os.getpid() not in {pid for _, pid in out}


def test_one_worker_runs_here(monkeypatch):
    monkeypatch.setenv(parallel.WORKERS_VARIABLE, "1")
    assert workers() == 1
    assert map_tasks(lambda i: os.getpid(), [0, 1]) == [os.getpid()] * 2


@forks
def test_a_worker_has_no_workers(monkeypatch):
    """A task that maps tasks of its own runs them in its own process."""
    monkeypatch.setenv(parallel.WORKERS_VARIABLE, "2")
    out = map_tasks(lambda i: (os.getpid(), map_tasks(lambda j: os.getpid(), [0, 1])), [0, 1])
    for pid, inner in out:
        assert inner == [pid, pid]


@forks
def test_an_exception_in_a_task_is_raised_here(monkeypatch):
    monkeypatch.setenv(parallel.WORKERS_VARIABLE, "2")

    def task(i: int) -> int:
        if i == 3:
            raise ValueError("task 3 failed")
        return i

    with pytest.raises(ValueError, match="task 3 failed"):
        map_tasks(task, list(range(5)))


@pytest.mark.parametrize("value", ["0", "two", "-1", "1.5"])
def test_a_bad_worker_count_is_a_value_error(monkeypatch, value):
    monkeypatch.setenv(parallel.WORKERS_VARIABLE, value)
    with pytest.raises(ValueError, match="VTRACK_WORKERS must be an integer >= 1"):
        workers()


def test_the_cli_says_so_on_one_line():
    env = dict(os.environ, VTRACK_WORKERS="many")
    r = subprocess.run([sys.executable, "-m", "vtrack", "experiment", "siim", "--runs", "2",
                        "--json"], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 2
    assert r.stderr == "error: experiment: VTRACK_WORKERS must be an integer >= 1, not 'many'\n"


@forks
def test_an_experiment_gives_the_same_json_on_one_worker_as_on_two(monkeypatch):
    """The filters side by side in two workers: the very same numbers as in one process (a
    filter does not depend on what runs beside it). The INS cases: tests/ins."""
    run = load_all()["fuzzy"].run
    monkeypatch.setenv(parallel.WORKERS_VARIABLE, "1")
    alone = json.dumps(run(2, 5).summary)
    monkeypatch.setenv(parallel.WORKERS_VARIABLE, "2")
    assert json.dumps(run(2, 5).summary) == alone


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(PR_SET_PDEATHSIG)")
def test_the_workers_die_with_a_killed_parent(tmp_path):
    """A parent killed outright (SIGKILL: no handler runs) takes its workers with it, at
    once, instead of leaving them to compute for nobody."""
    pids = tmp_path / "pids"
    script = (
        "import os, sys, time\n"
        "from vtrack.estimation.parallel import map_tasks\n"
        "def task(i):\n"
        f"    open({str(pids)!r}, 'a').write(f'{{os.getpid()}}\\n')\n"
        "    time.sleep(60)\n"
        "map_tasks(task, [0, 1])\n")
    env = dict(os.environ, VTRACK_WORKERS="2")
    parent = subprocess.Popen([sys.executable, "-c", script], env=env,
                              stderr=subprocess.PIPE)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and (not pids.exists()
                                           or len(pids.read_text().split()) < 2):
        time.sleep(0.05)
    workers_ = [int(p) for p in pids.read_text().split()]
    assert len(workers_) == 2
    parent.kill()
    parent.wait(timeout=10)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(p) for p in workers_):
        time.sleep(0.05)
    assert not any(_alive(p) for p in workers_)
    assert parent.stderr.read() == b""


def _alive(pid: int) -> bool:
    """The process exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False
