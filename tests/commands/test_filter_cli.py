"""`vtrack filter CONFIG.toml MEASUREMENTS.csv --out ESTIMATES.csv` (INTERFACE.md).

Round trips through real files compared with calling the core filter directly, every
bad-input case of the contract (exit 2, exactly one `error: ` line naming the file, no
ESTIMATES.csv), --rerun wiring, and the shipped example.
"""

import csv
import json
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from vtrack.cli import main
from vtrack.estimation.bounds import chi2_band
from vtrack.filter_kinds import make_filter
from vtrack.estimation.linalg import wrap_angle
from vtrack.estimation.models import (
    Bearings,
    ConstantAcceleration,
    Ranges,
    Unicycle,
    WienerVelocity,
    pose_measurement,
    position_measurement,
)

ROOT = Path(__file__).resolve().parents[2]

BEARINGS_TOML = """\
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
{extra}
[init]
x0 = [0.0, 0.0, 1.0, 0.0]
P0 = [0.1, 0.1, 10.0, 10.0]
"""


def _bearings_rows(n=60, seed=0):
    """A straight-ish path, bearings from both sensors, irregular times, missing cells."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.02, n))
    pos = np.stack([t * 1.0, 0.2 * np.sin(t)], axis=1)
    sensors = np.array([[1.0, -2.0], [1.0, 2.0]])
    z = np.arctan2(pos[:, None, 1] - sensors[:, 1], pos[:, None, 0] - sensors[:, 0])
    z = wrap_angle(z + 0.05 * rng.standard_normal(z.shape))
    cells = [[repr(float(v)) for v in row] for row in z]
    cells[5][0] = ""        # missing cell (empty)
    cells[9][1] = "nan"     # missing cell (nan)
    cells[14] = ["NaN", ""]  # all missing: predict only
    return t, cells


def _write_csv(path, header, t, cells):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for tk, row in zip(t, cells):
            w.writerow([repr(float(tk))] + list(row))


def _read_estimates(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=float)


def _direct(kind, motion, meas, x0, P0, dt0, t, z, u=None, **opts):
    """The reference: call the core filter object directly, row by row."""
    f = make_filter(kind, motion, meas, np.array(x0, float), np.array(P0, float), **opts)
    prev = t[0] - dt0
    out = []
    for k in range(len(t)):
        f.predict(t[k] - prev, None if u is None else u[k])
        f.update(z[k])
        prev = t[k]
        out.append(np.concatenate([[t[k]], f.x, f.P.ravel()]))
    return np.array(out)


def _cells_to_z(cells):
    return np.array([[np.nan if c.strip().lower() in ("", "nan") else float(c) for c in row]
                     for row in cells])


# ------------------------------------------------------------------------ round trips


@pytest.mark.parametrize("kind,extra,opts", [
    ("ukf", "", {}),
    ("ukf", "alpha = 0.5\nbeta = 2.0\nkappa = 0\n", {"alpha": 0.5, "beta": 2.0, "kappa": 0.0}),
    ("ekf", "", {}),
    ("ckf", "", {}),
    ("srukf", "", {}),
    ("iekf", "", {}),
    ("iekf", "max_iterations = 4\ntolerance = 0.01\n", {"max_iterations": 4, "tolerance": 0.01}),
    ("iekf", "damped = false\n", {"damped": False}),
    ("iplf", "", {}),
    ("iplf", 'rule = "unscented"\nalpha = 1.0\nkappa = 0\nmax_iterations = 8\n',
     {"rule": "unscented", "alpha": 1.0, "kappa": 0.0, "max_iterations": 8}),
    ("iplf", "damped = false\n", {"damped": False}),
])
def test_round_trip_bearings(tmp_path, capsys, kind, extra, opts):
    cfg = tmp_path / "config.toml"
    cfg.write_text(BEARINGS_TOML.format(kind=kind, extra=extra))
    t, cells = _bearings_rows()
    meas_csv = tmp_path / "meas.csv"
    _write_csv(meas_csv, ["t", "z0", "z1"], t, cells)
    out = tmp_path / "sub" / "est.csv"
    assert main(["filter", str(cfg), str(meas_csv), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    header, got = _read_estimates(out)
    n = 4
    assert header == (["t"] + [f"x{i}" for i in range(n)]
                      + [f"P{i}_{j}" for i in range(n) for j in range(n)])
    ref = _direct(kind, WienerVelocity(0.1), Bearings([[1.0, -2.0], [1.0, 2.0]], 0.05),
                  [0, 0, 1, 0], np.diag([0.1, 0.1, 10, 10]), 0.01, t, _cells_to_z(cells),
                  **opts)
    # full precision: repr round-trips, so the file holds exactly the filter's numbers
    np.testing.assert_array_equal(got, ref)
    assert len(got) == len(t)
    assert not [p for p in out.parent.iterdir() if p.name != "est.csv"]  # no temp files


def test_round_trip_other_models(tmp_path):
    """constant-acceleration + position (kf, full P0 matrix, per-measurement sigma),
    wiener-velocity + range (ekf), unicycle + pose with inputs (ukf, q per state)."""
    rng = np.random.default_rng(1)
    t = np.arange(1, 31) * 0.04

    # constant acceleration, linear position measurement, full P0
    P0 = np.diag([4.0, 4.0, 9.0, 9.0, 16.0, 16.0])
    P0[0, 2] = P0[2, 0] = 1.0
    rows = "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in r) + "]" for r in P0) + "]"
    (tmp_path / "ca.toml").write_text(f"""
[motion]
model = "constant-acceleration"
dt = 0.04
q = 2500
[measurement]
model = "position"
sigma = [1.5, 2.0]
[filter]
kind = "kf"
[init]
x0 = [0, 0, 10, 5, 0, 0]
P0 = {rows}
""")
    z = np.stack([10 * t, 5 * t], axis=1) + rng.normal(0, 1.5, (len(t), 2))
    cells = [[repr(float(v)) for v in r] for r in z]
    cells[3][1] = ""
    _write_csv(tmp_path / "ca.csv", ["t", "z0", "z1"], t, cells)
    assert main(["filter", str(tmp_path / "ca.toml"), str(tmp_path / "ca.csv"),
                 "--out", str(tmp_path / "ca_out.csv")]) == 0
    _, got = _read_estimates(tmp_path / "ca_out.csv")
    ref = _direct("kf", ConstantAcceleration(2500.0), position_measurement(6, [1.5, 2.0]),
                  [0, 0, 10, 5, 0, 0], P0, 0.04, t, _cells_to_z(cells))
    np.testing.assert_array_equal(got, ref)
    assert got.shape[1] == 1 + 6 + 36

    # range measurements
    sensors = [[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]]
    (tmp_path / "rg.toml").write_text(f"""
[motion]
model = "wiener-velocity"
dt = 0.04
q = 0.5
[measurement]
model = "range"
sensors = {sensors}
sigma = [0.1, 0.2, 0.1]
[filter]
kind = "ekf"
[init]
x0 = [1.0, 1.0, 1.0, 0.5]
P0 = [1, 1, 1, 1]
""")
    pos = np.stack([1 + t, 1 + 0.5 * t], axis=1)
    z = np.linalg.norm(pos[:, None] - np.array(sensors), axis=-1) + rng.normal(0, 0.1, (30, 3))
    cells = [[repr(float(v)) for v in r] for r in z]
    _write_csv(tmp_path / "rg.csv", ["t", "z0", "z1", "z2"], t, cells)
    assert main(["filter", str(tmp_path / "rg.toml"), str(tmp_path / "rg.csv"),
                 "--out", str(tmp_path / "rg_out.csv")]) == 0
    _, got = _read_estimates(tmp_path / "rg_out.csv")
    ref = _direct("ekf", WienerVelocity(0.5), Ranges(sensors, [0.1, 0.2, 0.1]),
                  [1, 1, 1, 0.5], np.eye(4), 0.04, t, z)
    np.testing.assert_array_equal(got, ref)

    # unicycle with inputs, pose measurement (heading near +-pi to exercise the wrap)
    (tmp_path / "uni.toml").write_text("""
[motion]
model = "unicycle"
dt = 1.0
q = [1e-6, 1e-6, 7.6e-5]
[measurement]
model = "pose"
sigma = [0.01, 0.01, 0.0175]
[filter]
kind = "ukf"
[init]
x0 = [1.0, 1.0, 3.1]
P0 = [0.01, 0.01, 0.01]
""")
    u = np.column_stack([np.full(30, 0.02), np.full(30, 0.05)])
    tu = np.arange(1, 31) * 1.0
    th = 3.1 + 0.05 * tu
    z = np.column_stack([1 + 0.02 * tu, 1 + 0.01 * tu, wrap_angle(th)])
    cells = [[repr(float(v)) for v in r] + [repr(float(a)) for a in uu]
             for r, uu in zip(z, u)]
    _write_csv(tmp_path / "uni.csv", ["t", "z0", "z1", "z2", "u_v", "u_omega"], tu, cells)
    assert main(["filter", str(tmp_path / "uni.toml"), str(tmp_path / "uni.csv"),
                 "--out", str(tmp_path / "uni_out.csv")]) == 0
    header, got = _read_estimates(tmp_path / "uni_out.csv")
    assert header[:4] == ["t", "x0", "x1", "x2"] and header[-1] == "P2_2"
    ref = _direct("ukf", Unicycle([1e-6, 1e-6, 7.6e-5]), pose_measurement([0.01, 0.01, 0.0175]),
                  [1, 1, 3.1], np.diag([0.01, 0.01, 0.01]), 1.0, tu, z, u)
    np.testing.assert_array_equal(got, ref)


def test_header_only_csv_gives_header_only_output(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text(BEARINGS_TOML.format(kind="ukf", extra=""))
    (tmp_path / "m.csv").write_text("t,z0,z1\n")
    assert main(["filter", str(cfg), str(tmp_path / "m.csv"), "--out",
                 str(tmp_path / "o.csv")]) == 0
    assert (tmp_path / "o.csv").read_text().count("\n") == 1


# ------------------------------------------------------------------- consistency report


def _model_matched_log(tmp_path, steps=400, seed=12):
    """Bearings of a target that moves exactly as the config's model says (x0 drawn from the
    prior), so a filter with the config's sigma is consistent; two cells missing. (A 95%
    test rejects a consistent filter on 5% of logs: seed 11 gives 1.107 against the upper
    limit 1.101 for all four kinds; seeds 12-15 give 0.96-0.99.)"""
    rng = np.random.default_rng(seed)
    motion = WienerVelocity(0.1)
    F, L = motion.transition(0.01), np.linalg.cholesky(motion.Q(0.01))
    x = np.array([0.0, 0.0, 1.0, 0.0]) + np.sqrt([0.1, 0.1, 10.0, 10.0]) * rng.normal(size=4)
    z = []
    for _ in range(steps):
        x = F @ x + L @ rng.normal(size=4)
        z.append(Bearings([[1.0, -2.0], [1.0, 2.0]], 0.05).h(x) + 0.05 * rng.normal(size=2))
    cells = [[repr(float(v)) for v in wrap_angle(np.array(row))] for row in z]
    cells[3][0], cells[8] = "", ["", ""]
    t = 0.01 * np.arange(1, steps + 1)
    _write_csv(tmp_path / "meas.csv", ["t", "z0", "z1"], t, cells)
    return t, cells


@pytest.mark.parametrize("kind", ["ekf", "iekf", "ukf", "iplf"])
def test_report_gives_the_nis_test_of_the_run(tmp_path, capsys, kind):
    """--report: sum NIS / sum dof of the run against chi2_band(1, sum dof). The NIS are the
    filter's own (recomputed here through the core filter); with the true sigma the test
    passes, with sigma 10x too small it fails."""
    t, cells = _model_matched_log(tmp_path)
    reports = {}
    for sigma in (0.05, 0.005):
        cfg = tmp_path / "config.toml"
        cfg.write_text(BEARINGS_TOML.format(kind=kind, extra="").replace(
            "sigma = 0.05", f"sigma = {sigma}"))
        report = tmp_path / f"report{sigma}.json"
        assert main(["filter", str(cfg), str(tmp_path / "meas.csv"), "--out",
                     str(tmp_path / "est.csv"), "--report", str(report)]) == 0
        reports[sigma] = json.loads(report.read_text())
    good, bad = reports[0.05], reports[0.005]
    assert good["rows"] == 400 and good["updates"] == 399 and good["nis_dof_sum"] == 797
    f = make_filter(kind, WienerVelocity(0.1), Bearings([[1.0, -2.0], [1.0, 2.0]], 0.05),
                    np.array([0.0, 0.0, 1.0, 0.0]), np.diag([0.1, 0.1, 10.0, 10.0]))
    nis = [info.nis for zk in _cells_to_z(cells) if (info := f.step(0.01, zk)) is not None]
    assert good["nis_per_dof"] == pytest.approx(sum(nis) / 797, rel=1e-12)
    lo, hi = chi2_band(1, 797)
    assert good["nis_per_dof_band"] == pytest.approx([lo, hi])
    assert good["nis_consistent"] is True, good
    assert bad["nis_consistent"] is False and bad["nis_per_dof"] > hi, bad
    assert good["kind"] == kind and capsys.readouterr().err == ""


# ------------------------------------------------------------------------ bad inputs

GOOD_CSV = "t,z0,z1\n0.01,2.0,-2.0\n0.02,1.95,-2.01\n0.03,1.9,-2.02\n"


def _toml(kind="ukf", extra="", **replace):
    text = BEARINGS_TOML.format(kind=kind, extra=extra)
    for old, new in replace.items():
        old = old.replace("__", " = ")
        assert old in text, old
        text = text.replace(old, new)
    return text


BAD_CASES = {
    # name: (config text or None for a missing file, csv text or None, file named, words)
    "missing config file": (None, GOOD_CSV, "config", ["no such file"]),
    "missing measurements file": (_toml(), None, "meas", ["no such file"]),
    "malformed toml": ("[motion\nmodel = 'x'\n", GOOD_CSV, "config", ["malformed TOML"]),
    "unknown motion model": (_toml(**{'"wiener-velocity"': '"brownian"'}), GOOD_CSV,
                             "config", ["unknown motion model", "brownian"]),
    "unknown measurement model": (_toml(**{'"bearings"': '"sonar"'}), GOOD_CSV, "config",
                                  ["unknown measurement model", "sonar"]),
    "unknown filter kind": (_toml(kind="pf"), GOOD_CSV, "config",
                            ["unknown filter kind", "'pf'", "ekf", "ukf", "ckf", "srukf"]),
    "unknown key": (_toml(**{"q = 0.1": "q = 0.1\nqq = 2"}), GOOD_CSV, "config",
                    ["unknown key", "qq"]),
    "unknown section": (_toml() + "\n[extras]\na = 1\n", GOOD_CSV, "config", ["extras"]),
    "missing key": (_toml(**{"dt = 0.01\n": ""}), GOOD_CSV, "config", ["missing", "dt"]),
    "missing section": (_toml().split("[filter]")[0] + "[init]\nx0 = [0,0,1,0]\n"
                        "P0 = [1,1,1,1]\n", GOOD_CSV, "config", ["missing section", "filter"]),
    "unknown filter option": (_toml(extra="gamma = 0.5\n"), GOOD_CSV, "config",
                              ["gamma", "alpha"]),
    "option for a kind without options": (_toml(kind="ekf", extra="alpha = 1.0\n"), GOOD_CSV,
                                          "config", ["alpha"]),
    "non-numeric q": (_toml(**{"q = 0.1": 'q = "lots"'}), GOOD_CSV, "config", ["q", "number"]),
    "negative dt": (_toml(**{"dt = 0.01": "dt = -0.01"}), GOOD_CSV, "config", ["dt", "> 0"]),
    "wrong sigma length": (_toml(**{"sigma = 0.05": "sigma = [0.05, 0.05, 0.05]"}), GOOD_CSV,
                           "config", ["sigma", "2"]),
    "bad sensors": (_toml(**{"sensors = [[1.0, -2.0], [1.0, 2.0]]": "sensors = [[1.0], [2]]"}),
                    GOOD_CSV, "config", ["sensors"]),
    "pose without unicycle": (_toml(**{'"bearings"': '"pose"',
                                       "sensors = [[1.0, -2.0], [1.0, 2.0]]\n": ""}),
                              GOOD_CSV, "config", ["pose", "unicycle"]),
    "kf with a nonlinear model": (_toml(kind="kf"), GOOD_CSV, "config", ["linear"]),
    "unknown iplf rule": (_toml(kind="iplf", extra='rule = "gauss"\n'), GOOD_CSV, "config",
                          ["rule", "gauss", "cubature"]),
    "bad iekf max_iterations": (_toml(kind="iekf", extra="max_iterations = 0\n"), GOOD_CSV,
                                "config", ["max_iterations", ">= 1"]),
    "wrong P0 length": (_toml(**{"P0 = [0.1, 0.1, 10.0, 10.0]": "P0 = [0.1, 0.1, 10.0]"}),
                        GOOD_CSV, "config", ["P0"]),
    "wrong P0 matrix shape": (_toml(**{"P0 = [0.1, 0.1, 10.0, 10.0]":
                                       "P0 = [[1,0,0],[0,1,0],[0,0,1],[0,0,1]]"}),
                              GOOD_CSV, "config", ["P0", "row"]),
    "P0 not positive definite": (_toml(**{"P0 = [0.1, 0.1, 10.0, 10.0]":
                                          "P0 = [[1,2,0,0],[2,1,0,0],[0,0,1,0],[0,0,0,1]]"}),
                                 GOOD_CSV, "config", ["P0", "positive definite"]),
    "P0 not symmetric": (_toml(**{"P0 = [0.1, 0.1, 10.0, 10.0]":
                                  "P0 = [[1,0.5,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]"}),
                         GOOD_CSV, "config", ["P0", "symmetric"]),
    "wrong x0 length": (_toml(**{"x0 = [0.0, 0.0, 1.0, 0.0]": "x0 = [0.0, 0.0]"}), GOOD_CSV,
                        "config", ["x0"]),
    "non-numeric cell": (_toml(), GOOD_CSV.replace("1.95", "abc"), "meas",
                         ["line 3", "abc"]),
    "inf cell": (_toml(), GOOD_CSV.replace("1.95", "inf"), "meas", ["line 3", "inf"]),
    "minus inf cell": (_toml(), GOOD_CSV.replace("-2.02", "-Infinity"), "meas", ["line 4"]),
    "wrong-length row (short)": (_toml(), GOOD_CSV.replace("1.95,-2.01", "1.95"), "meas",
                                 ["line 3", "cells"]),
    "wrong-length row (long)": (_toml(), GOOD_CSV.replace("1.9,-2.02", "1.9,-2.02,7"), "meas",
                                ["line 4", "cells"]),
    "non-increasing t": (_toml(), GOOD_CSV.replace("0.03,", "0.02,"), "meas",
                         ["line 4", "increasing"]),
    "decreasing t": (_toml(), GOOD_CSV.replace("0.03,", "0.001,"), "meas", ["line 4"]),
    "nan t": (_toml(), GOOD_CSV.replace("0.02,", "nan,"), "meas", ["line 3", "t"]),
    "header mismatch": (_toml(), "t,z0\n0.01,2.0\n", "meas", ["header", "t,z0,z1"]),
    "header with extra z": (_toml(), "t,z0,z1,z2\n0.01,2.0,1,1\n", "meas", ["header"]),
    "empty measurements file": (_toml(), "", "meas", ["empty"]),
    "estimation failure": (_toml(), GOOD_CSV + "1e300,1.9,-2.0\n", "meas",
                           ["line 5", "failed"]),
}


@pytest.mark.parametrize("case", list(BAD_CASES))
def test_bad_input_exits_2_with_one_error_line(tmp_path, capsys, case):
    config_text, csv_text, named, words = BAD_CASES[case]
    cfg, meas = tmp_path / "config.toml", tmp_path / "meas.csv"
    if config_text is not None:
        cfg.write_text(config_text)
    if csv_text is not None:
        meas.write_text(csv_text)
    outdir = tmp_path / "out"
    out = outdir / "estimates.csv"
    rc = main(["filter", str(cfg), str(meas), "--out", str(out)])
    captured = capsys.readouterr()
    assert rc == 2
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("error: ")
    assert str(cfg if named == "config" else meas) in lines[0]
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert captured.out == ""
    assert not out.exists()
    assert not outdir.exists() or not list(outdir.iterdir())


def test_existing_output_untouched_on_error(tmp_path, capsys):
    cfg, meas, out = tmp_path / "c.toml", tmp_path / "m.csv", tmp_path / "e.csv"
    cfg.write_text(_toml())
    meas.write_text(GOOD_CSV.replace("1.95", "inf"))
    out.write_text("previous\n")
    assert main(["filter", str(cfg), str(meas), "--out", str(out)]) == 2
    assert out.read_text() == "previous\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml", "e.csv", "m.csv"]


def test_unicycle_input_cells_are_required(tmp_path, capsys):
    cfg, meas, out = tmp_path / "c.toml", tmp_path / "m.csv", tmp_path / "e.csv"
    cfg.write_text("""
[motion]
model = "unicycle"
dt = 1.0
q = 1e-4
[measurement]
model = "position"
sigma = 0.01
[filter]
kind = "ekf"
[init]
x0 = [0, 0, 0]
P0 = [1, 1, 1]
""")
    meas.write_text("t,z0,z1,u_v,u_omega\n1,0.1,0,0.1,0\n2,0.2,0,,0\n")
    assert main(["filter", str(cfg), str(meas), "--out", str(out)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "line 3" in err[0] and "u_v" in err[0]
    assert not out.exists()
    meas.write_text("t,z0,z1\n1,0.1,0\n")  # inputs missing from the header
    assert main(["filter", str(cfg), str(meas), "--out", str(out)]) == 2
    assert "u_v,u_omega" in capsys.readouterr().err


def test_missing_out_option_is_a_usage_error(tmp_path, capsys):
    assert main(["filter", "a.toml", "b.csv"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "--out" in err[0]


def test_real_process_stderr_is_one_line(tmp_path):
    """Through `python -m vtrack` (no numpy warnings or traceback on stderr)."""
    cfg, meas, out = tmp_path / "c.toml", tmp_path / "m.csv", tmp_path / "e.csv"
    cfg.write_text(_toml())
    meas.write_text(GOOD_CSV + "1e300,1.9,-2.0\n")
    proc = subprocess.run([sys.executable, "-m", "vtrack", "filter", str(cfg), str(meas),
                           "--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("error: ")
    assert not out.exists()


# ---------------------------------------------------------------------------- --rerun


def test_rerun_calls_the_logger(tmp_path, monkeypatch):
    calls = []
    fake = types.ModuleType("vtrack.viz.rerun_log")
    fake.log_filter_run = lambda *a: calls.append(a)
    import vtrack.viz

    monkeypatch.delattr(vtrack.viz, "rerun_log", raising=False)
    monkeypatch.setitem(sys.modules, "vtrack.viz.rerun_log", fake)
    cfg, meas, out = tmp_path / "c.toml", tmp_path / "m.csv", tmp_path / "e.csv"
    cfg.write_text(_toml())
    meas.write_text(GOOD_CSV.replace("1.95", ""))
    rrd = tmp_path / "run.rrd"
    assert main(["filter", str(cfg), str(meas), "--out", str(out), "--rerun", str(rrd)]) == 0
    (times, estimates, covariances, measurements, sensors, path), = calls
    _, est = _read_estimates(out)
    np.testing.assert_array_equal(times, est[:, 0])
    np.testing.assert_array_equal(estimates, est[:, 1:5])
    np.testing.assert_array_equal(covariances.reshape(len(times), -1), est[:, 5:])
    assert measurements.shape == (3, 2) and np.isnan(measurements[1, 0])
    np.testing.assert_array_equal(sensors, [[1.0, -2.0], [1.0, 2.0]])
    assert path == str(rrd)


def _rrd_rows(path, entity: str, component: str) -> list[tuple[int | None, object]]:
    """(time in ns or None for static rows, value) of one component of one entity of an .rrd
    file, read back with rerun's reader, over all chunks, in time order."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    out = []
    for ch in RrdReader(str(path)).stream():
        if ch.entity_path != entity:
            continue
        rb = ch.to_record_batch()
        if component not in rb.schema.names:
            continue
        times = (rb.column("time").cast(pa.int64()).to_pylist() if "time" in rb.schema.names
                 else [None] * rb.num_rows)
        out.extend(zip(times, rb.column(component).to_pylist()))
    return sorted(out, key=lambda tv: -1 if tv[0] is None else tv[0])


def test_rerun_recording_holds_the_estimates(tmp_path):
    """The .rrd read back: each state component's series equals ESTIMATES.csv's column
    (times and values), the logged path is the estimated positions, every point of each
    time's 2-sigma ellipse lies at Mahalanobis distance 2 under the CSV's position
    covariance, and the sensors are the config's."""
    pytest.importorskip("rerun")
    cfg, meas, out = tmp_path / "c.toml", tmp_path / "m.csv", tmp_path / "e.csv"
    cfg.write_text(_toml())
    t, cells = _bearings_rows()
    _write_csv(meas, ["t", "z0", "z1"], t, cells)
    rrd = tmp_path / "run.rrd"
    assert main(["filter", str(cfg), str(meas), "--out", str(out), "--rerun", str(rrd)]) == 0
    _, est = _read_estimates(out)
    times_ns = np.round(est[:, 0] * 1e9).astype(np.int64)    # rerun's duration: ns
    for k in range(4):
        series = _rrd_rows(rrd, f"/state/x{k}", "Scalars:scalars")
        assert np.abs(np.array([tv[0] for tv in series]) - times_ns).max() <= 1  # ns rounding
        np.testing.assert_array_equal([v[0] for _, v in series], est[:, 1 + k])
    (_, strips), = _rrd_rows(rrd, "/plane/estimate/path", "LineStrips2D:strips")
    np.testing.assert_allclose(np.array(strips[0]), est[:, 1:3], rtol=1e-6, atol=1e-7)
    ellipses = _rrd_rows(rrd, "/plane/estimate/ellipse", "LineStrips2D:strips")
    assert np.abs(np.array([tv[0] for tv in ellipses]) - times_ns).max() <= 1
    for row, (_, strip) in zip(est, ellipses):
        pts = np.array(strip[0], dtype=float) - row[1:3]
        P = row[5:].reshape(4, 4)[:2, :2]
        d2 = np.einsum("ni,ij,nj->n", pts, np.linalg.inv(P), pts)
        np.testing.assert_allclose(d2, 4.0, rtol=1e-4)
    (_, sensors), = _rrd_rows(rrd, "/plane/sensors", "Points2D:positions")
    np.testing.assert_array_equal(sensors, [[1.0, -2.0], [1.0, 2.0]])


def _missing_extra(*args):
    from vtrack.errors import MissingExtraError

    raise MissingExtraError("rerun", "rerun-sdk")


@pytest.mark.parametrize("how", ["logger module missing", "rerun-sdk missing"])
def test_rerun_unavailable_is_an_input_error(tmp_path, monkeypatch, capsys, how):
    import vtrack.viz

    monkeypatch.delattr(vtrack.viz, "rerun_log", raising=False)
    if how == "logger module missing":
        monkeypatch.setitem(sys.modules, "vtrack.viz.rerun_log", None)  # import fails
    else:
        fake = types.ModuleType("vtrack.viz.rerun_log")
        fake.log_filter_run = _missing_extra
        monkeypatch.setitem(sys.modules, "vtrack.viz.rerun_log", fake)
    cfg, meas, out = tmp_path / "c.toml", tmp_path / "m.csv", tmp_path / "e.csv"
    cfg.write_text(_toml())
    meas.write_text(GOOD_CSV)
    rc = main(["filter", str(cfg), str(meas), "--out", str(out), "--rerun",
               str(tmp_path / "r.rrd")])
    err = capsys.readouterr().err.splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("error: ") and "rerun" in err[0]
    assert not out.exists()


# ---------------------------------------------------------------------------- example


def test_shipped_example_runs(tmp_path):
    """examples/README.md's two commands: simulate the seed-000 turning path, filter it."""
    meas, truth, out = tmp_path / "bearings.csv", tmp_path / "truth.csv", tmp_path / "e.csv"
    subprocess.run([sys.executable, str(ROOT / "examples" / "make_bearings_csv.py"),
                    str(meas), "--seed", "3", "--truth", str(truth)], check=True)
    assert main(["filter", str(ROOT / "examples" / "bearings.toml"), str(meas),
                 "--out", str(out)]) == 0
    _, est = _read_estimates(out)
    tr = np.loadtxt(truth, delimiter=",", skiprows=1)
    assert est.shape == (500, 21)
    np.testing.assert_array_equal(est[:, 0], tr[:, 0])
    rmse = np.sqrt(np.mean(np.sum((est[:, 1:3] - tr[:, 1:3]) ** 2, axis=1)))
    assert rmse < 0.25  # seed-000 level is ~0.115 (SEEDS 2.5)
