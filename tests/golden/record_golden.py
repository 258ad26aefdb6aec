#!/usr/bin/env python
"""Record the outputs that refactors of the estimation core must leave unchanged.

Run once against the code BEFORE a refactor (the files in this folder were recorded from
commit a7d84d5, before the filter registry, the hooks and the Monte Carlo harness):

    git archive a7d84d5 | tar -x -C /tmp/base
    cd /tmp/base && OPENBLAS_CORETYPE=Haswell PYTHONPATH=/tmp/base \
        /path/to/vtrack/.venv/bin/python /path/to/vtrack/tests/golden/record_golden.py

The tests compare with these files within a tolerance (tests/golden/tolerance.py: 1e-9
relative to the quantity's magnitude), not bit for bit: OpenBLAS's and NumPy's kernels
differ from CPU to CPU and round the last bits differently, so no recording is bit-exact on
every machine, and the tests run on whatever kernels the machine picks. The recording still
names its OpenBLAS kernels, Haswell (AVX2), so that a re-recording can be checked byte for
byte against the SHA-256s below. (Recorded first with SkylakeX kernels; re-recorded from
a7d84d5 with Haswell's once the machines changed, after checking that a7d84d5 with
SkylakeX's reproduces the first recording byte for byte.)

It writes, next to this file:
* filter/<input>.csv: measurement logs (made here once, deterministic) and filter/expected.json:
  for each (config, kind, options, log) the exit code of `vtrack filter`, the SHA-256 of its
  ESTIMATES.csv, its row count and every 25th row at full precision (or the one-line error);
  filter/estimates.json.gz: each case's whole ESTIMATES.csv (the bytes the SHA-256 names;
  added later, after checking that the code on Haswell's kernels still gives those bytes);
* experiments/<name>.json: `vtrack experiment NAME --json` on the shrunk settings the
  experiment JSON tests use (SHRINK below); those tests call assert_unchanged;
* experiments_full/<name>.json: `vtrack experiment NAME --json --runs 4 --seed 1` (full
  size; tests/golden/check_outputs.py compares them, too slow for the suite).

tests/experiments/test_outputs_unchanged.py (the filter cases) and the experiments' JSON tests
(assert_unchanged) compare the current code with these files.
"""

from __future__ import annotations

import contextlib
import csv
import gzip
import hashlib
import io
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from tolerance import json_differences

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

# ------------------------------------------------------------------------ filter inputs

BEARINGS = """\
[motion]
model = "wiener-velocity"
dt = 0.01
q = 0.1

[measurement]
model = "bearings"
sensors = [[1.0, -2.0], [1.0, 2.0]]
sigma = 0.05

[filter]
kind = "{kind}"
{options}
[init]
x0 = [0.0, 0.0, 0.0, 0.0]
P0 = [0.1, 0.1, 10.0, 10.0]
"""

LINEAR = """\
[motion]
model = "constant-acceleration"
dt = 0.04
q = 2.0

[measurement]
model = "position"
sigma = [0.5, 0.8]

[filter]
kind = "{kind}"
{options}
[init]
x0 = [0.0, 0.0, 1.0, 0.5, 0.0, 0.0]
P0 = [1.0, 1.0, 4.0, 4.0, 1.0, 1.0]
"""

RANGE = """\
[motion]
model = "wiener-velocity"
dt = 0.1
q = 0.05

[measurement]
model = "range"
sensors = [[0.0, 0.0], [10.0, 0.0]]
sigma = 0.1

[filter]
kind = "{kind}"
{options}
[init]
x0 = [3.0, 4.0, 0.5, 0.0]
P0 = [1.0, 1.0, 0.5, 0.5]
"""

UNICYCLE = """\
[motion]
model = "unicycle"
dt = 1.0
q = [0.01, 0.01, 0.001]

[measurement]
model = "pose"
sigma = [0.1, 0.1, 0.05]

[filter]
kind = "{kind}"
{options}
[init]
x0 = [0.0, 0.0, 3.0]
P0 = [0.5, 0.5, 0.2]
"""

CONFIGS = {"bearings": BEARINGS, "linear": LINEAR, "range": RANGE, "unicycle": UNICYCLE}

# (config, kind, TOML option lines, measurement log)
CASES: list[tuple[str, str, str, str]] = [
    *[("bearings", k, "", log) for log in ("bearings", "bearings_missing")
      for k in ("ekf", "ukf", "ckf", "srukf", "crukf", "ankf1", "ankf2", "fuzzy-r", "fuzzy-q",
                "siim-ekf")],
    ("bearings", "ukf", "alpha = 0.5\nbeta = 2.0\nkappa = 0\n", "bearings"),
    ("bearings", "ankf1", "window = 10\nadapt_q = true\n", "bearings_missing"),
    ("bearings", "ankf2", "multiple_factors = true\nfade_prior = true\n", "bearings_missing"),
    ("bearings", "fuzzy-r", "rules = 3\nwindow = 8\n", "bearings_missing"),
    ("bearings", "siim-ekf", "gamma = 0.01\n", "bearings"),
    *[("linear", k, "", "linear") for k in ("kf", "ekf", "ukf", "ankf1", "ankf2", "fuzzy-r",
                                             "fuzzy-q", "siim-ekf")],
    *[("range", k, "", "range") for k in ("ekf", "ukf", "ckf", "siim-ekf", "ankf1")],
    *[("unicycle", k, "", "unicycle") for k in ("ekf", "ukf", "ckf", "srukf", "fuzzy-q")],
]


def _write_log(path: Path, header: list[str], t: np.ndarray, cells: list[list[str]]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for tk, row in zip(t, cells):
            w.writerow([repr(float(tk))] + row)


def make_logs(folder: Path) -> None:
    """The measurement logs (deterministic; only run when recording)."""
    sys.path.insert(0, str(ROOT / "examples"))
    from make_bearings_csv import simulate

    t, _, z = simulate(0)
    _write_log(folder / "bearings.csv", ["t", "z0", "z1"], t,
               [[repr(float(v)) for v in row] for row in z])
    cells = [[repr(float(v)) for v in row] for row in z[:200]]
    for k, row in enumerate(cells):
        if k % 7 == 3:
            row[0] = ""
        if k % 11 == 5:
            row[1] = "nan"
        if k % 50 == 25:
            row[0], row[1] = "", ""
    _write_log(folder / "bearings_missing.csv", ["t", "z0", "z1"], t[:200], cells)

    rng = np.random.default_rng(14)
    t = np.arange(1, 101) * 0.04
    pos = np.stack([t + 0.3 * t**2, 0.5 * t - 0.2 * t**2], axis=1)
    z = pos + rng.normal(size=pos.shape) * [0.5, 0.8]
    cells = [[repr(float(v)) for v in row] for row in z]
    cells[10][0] = ""
    cells[20] = ["", ""]
    _write_log(folder / "linear.csv", ["t", "z0", "z1"], t, cells)

    t = np.arange(1, 101) * 0.1
    pos = np.stack([3.0 + 0.5 * t, 4.0 + 0.1 * np.sin(t)], axis=1)
    sensors = np.array([[0.0, 0.0], [10.0, 0.0]])
    r = np.linalg.norm(pos[:, None, :] - sensors, axis=-1) + 0.1 * rng.normal(size=(100, 2))
    cells = [[repr(float(v)) for v in row] for row in r]
    cells[30][1] = "nan"
    _write_log(folder / "range.csv", ["t", "z0", "z1"], t, cells)

    t = np.arange(1, 81) * 1.0
    x = np.array([0.0, 0.0, 3.0])
    rows = []
    for k in range(80):
        v, om = 0.5, 0.05 * np.sin(0.1 * k)
        x = np.array([x[0], x[1], x[2] + om])
        x[0] += v * np.cos(x[2])
        x[1] += v * np.sin(x[2])
        zk = x + rng.normal(size=3) * [0.1, 0.1, 0.05]
        zk[2] = np.pi - np.mod(np.pi - zk[2], 2 * np.pi)
        rows.append([repr(float(c)) for c in zk] + [repr(v), repr(float(om))])
    _write_log(folder / "unicycle.csv", ["t", "z0", "z1", "z2", "u_v", "u_omega"], t, rows)


def run_filter_case(folder: Path, tmp: Path, config: str, kind: str, options: str, log: str
                    ) -> tuple[dict[str, object], str | None]:
    """`vtrack filter` in-process on one case: its record (exit code, hash, row count,
    sampled rows, or the error) and its whole ESTIMATES.csv (None after an error)."""
    from vtrack.cli import main

    cfg = tmp / "config.toml"
    cfg.write_text(CONFIGS[config].format(kind=kind, options=options))
    out = tmp / "estimates.csv"
    out.unlink(missing_ok=True)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["filter", str(cfg), str(folder / f"{log}.csv"), "--out", str(out)])
    if code != 0:
        return {"code": code, "error": err.getvalue().replace(str(folder), "<golden>")
                .replace(str(tmp), "<tmp>")}, None
    data = out.read_bytes()
    rows = data.decode().splitlines()
    return {"code": 0, "sha256": hashlib.sha256(data).hexdigest(), "rows": len(rows),
            "sampled": {str(i): rows[i] for i in range(0, len(rows), 25)}}, data.decode()


def case_key(config: str, kind: str, options: str, log: str) -> str:
    return f"{config}|{kind}|{options.strip().replace(chr(10), ';')}|{log}"


ESTIMATES = "estimates.json.gz"   # in filter/: case key -> its whole ESTIMATES.csv


def write_estimates(path: Path, estimates: dict[str, str]) -> None:
    """Write case key -> ESTIMATES.csv text, gzip-compressed with no time stamp (the same
    estimates give the same bytes)."""
    data = json.dumps(estimates, indent=0, sort_keys=True).encode()
    path.write_bytes(gzip.compress(data, compresslevel=9, mtime=0))


def read_estimates(path: Path) -> dict[str, str]:
    return json.loads(gzip.decompress(path.read_bytes()))


# ------------------------------------------------------------------ experiment shrinks


def _shrink_fuzzy(fz):  # noqa: ANN001, ANN202
    return {"STEPS": 120, "CASES": {"E3": fz.CASES["E3"]}}


def _shrink_robot(rb):  # noqa: ANN001, ANN202
    return {"PAPER": replace(rb.PAPER, steps=40),
            "CASES": {"unicycle-alpha1": (replace(rb.UNICYCLE, alpha=1.0, beta=2.0, kappa=0.0,
                                                  steps=40), "small", True)}}


def _shrink_siim(si):  # noqa: ANN001, ANN202
    original = si.Scenario2
    return {"GAMMA_SWEEP": (1e-2,), "Scenario2": lambda: original(samples=60)}


def _shrink_ins(ins):  # noqa: ANN001, ANN202
    return {"HEADLINE": ins.Scenario(duration=30.0),
            "OUTAGE": ins.Scenario(duration=40.0, outages=((15.0, 25.0),)),
            "CAR": ins.Scenario(vehicle="car", duration=30.0)}


# name -> (module, module attributes to replace, runs, seed): the experiment tests' settings
SHRINK = {
    "bearings-2": ("bearings", None, 2, 7),
    "bearings-3": ("bearings", None, 2, 7),
    "ankf": ("ankf", None, 2, 3),
    "fuzzy": ("fuzzy", _shrink_fuzzy, 3, 4),
    "robot": ("robot", _shrink_robot, 2, 3),
    "siim": ("siim", _shrink_siim, 20, 1),
    "ins": ("ins", _shrink_ins, 2, 5),
}


@contextlib.contextmanager
def shrunk(name: str):  # noqa: ANN201
    """The experiment module with the SHRINK attributes in place (restored afterwards)."""
    import importlib

    module_name, make, _, _ = SHRINK[name]
    mod = importlib.import_module(f"vtrack.experiments.{module_name}")
    saved = {}
    if make is not None:
        for attr, value in make(mod).items():
            saved[attr] = getattr(mod, attr)
            setattr(mod, attr, value)
    try:
        yield
    finally:
        for attr, value in saved.items():
            setattr(mod, attr, value)


def experiment_json(name: str, runs: int, seed: int) -> dict:
    from vtrack.cli import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["experiment", name, "--runs", str(runs), "--seed", str(seed),
                     "--json"]) == 0
    return json.loads(buf.getvalue())


def assert_unchanged(name: str, summary: dict) -> None:
    """`summary`, the JSON of experiment `name` on its SHRINK settings, holds every value
    recorded in experiments/<name>.json (floats within tolerance.py's, the rest exactly;
    new keys may be added)."""
    want = json.loads((HERE / "experiments" / f"{name}.json").read_text())
    diff = json_differences(want, json.loads(json.dumps(summary)))
    assert not diff, "\n".join(diff[:20])


def main() -> None:
    import tempfile

    filt = HERE / "filter"
    filt.mkdir(exist_ok=True)
    make_logs(filt)
    expected, estimates = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for case in CASES:
            expected[case_key(*case)], text = run_filter_case(filt, Path(tmp), *case)
            if text is not None:
                estimates[case_key(*case)] = text
    (filt / "expected.json").write_text(json.dumps(expected, indent=1, sort_keys=True) + "\n")
    write_estimates(filt / ESTIMATES, estimates)
    for sub in ("experiments", "experiments_full"):
        (HERE / sub).mkdir(exist_ok=True)
    for name, (_, _, runs, seed) in SHRINK.items():
        with shrunk(name):
            data = experiment_json(name, runs, seed)
        (HERE / "experiments" / f"{name}.json").write_text(json.dumps(data, sort_keys=True))
    if "--full" in sys.argv:
        for name in SHRINK:
            data = experiment_json(name, 4, 1)
            (HERE / "experiments_full" / f"{name}.json").write_text(
                json.dumps(data, sort_keys=True))


if __name__ == "__main__":
    main()
