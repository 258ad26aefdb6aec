"""How every golden test compares the current outputs with the recorded ones.

A float agrees when |got - want| <= rtol * max(|want|, floor), rtol = RTOL = 1e-9, and the
floor is the magnitude of the quantity it belongs to, so that a near-cancellation (1e-32
where a covariance is zero in theory) is held to the quantity's precision, not its own:
* a number in a JSON list: the largest |number| of the list (nested lists included);
* the numbers under a JSON key `A_minus_B` (a paired difference): |A|, its sibling;
* a state x_i in ESTIMATES.csv: its standard deviation sqrt(P_ii) on that row; a
  covariance P_ij: sqrt(P_ii P_jj) on that row (Cauchy-Schwarz);
* any other number: none (relative to itself).
Everything else (ints, bools, strings, None, keys, list lengths, row and cell counts,
non-numeric cells) compares exactly; NaN equals NaN; an infinity only itself.

Why 1e-9: another processor's OpenBLAS and NumPy kernels sum in other orders and round the
last bits differently, and the filters carry that into every output. Against the recording
(OpenBLAS's Haswell kernels), OpenBLAS's Prescott, Nehalem, Sandybridge and SkylakeX kernels
and NumPy without its AVX2/AVX-512 loops change most of the filter cases' 230700 floats,
by at most 1.3e-12 of the magnitudes above, and a third of the experiments' 1447, by at most
4.8e-11 (a filter's ANEES of 1.2e7, a paired difference of two filters' errors). 1e-9 is
20 times above that; a model parameter changed by 1e-8 relative already fails every filter
case it reaches. Three kinds of output amplify rounding far more:
* sigma points with a small alpha: weights up to A = |1 - L / (alpha^2 (L + kappa))| cancel
  in every weighted sum, leaving about A * EPS of precision; a JSON block whose `config`
  names alpha, kappa and L is held to max(RTOL, 100 * A * EPS) (the robot experiment's
  paper setting, alpha = 1e-4, L = 9: A = 1.1e8, 2.4e-6; measured up to 6.4e-8);
* a diverged filter: rounding differences grow with it until digits differ (the cube-root
  UKF's covariance grows tenfold every 20 steps on the bearings log, and its differences
  from 1e-13 to 1e-6 between steps 180 and 200). A JSON block that recorded `diverged` or
  `diverged_runs` above 0 keeps that count above 0 and its other numbers' types (a float's
  finiteness), not their values (its repair counts vary too); so do the rows of an
  ESTIMATES.csv from the first whose variance exceeds DIVERGED = 10 times the first row's
  largest (the converging cases never exceed 1.42 times);
* the paper's cube-root UKF (`crukf`, unsound: vtrack/experiments/robot.py) is chaotic even
  where it does not diverge: its covariance repairs are branches that rounding decides. In
  the full-size robot runs (tests/golden/check_outputs.py) OpenBLAS's Prescott kernels turn
  its 41 repairs into 47 and move its ANEES by 3e-2 (by 7e-4 where it repairs nothing, with
  a covariance trace of 1.6e5). Its JSON blocks compare like diverged ones; its
  ESTIMATES.csv rows, until it diverges, are reproducible and held to RTOL.
"""

from __future__ import annotations

import csv
import io
import math
import re

RTOL = 1e-9
EPS = 2.220446049250313e-16       # the spacing of doubles at 1
DIVERGED = 10.0                   # variance growth beyond the first row that marks divergence
DIVERGENCE_COUNTS = ("diverged", "diverged_runs")    # the experiments' counts of diverged runs
CHAOTIC = ("crukf",)              # kinds whose JSON blocks are compared like diverged ones


def _number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _magnitude(values: list) -> float:
    """The largest finite |number| in a JSON list, nested lists included."""
    out = 0.0
    for v in values:
        if isinstance(v, list):
            out = max(out, _magnitude(v))
        elif _number(v) and math.isfinite(v):
            out = max(out, abs(v))
    return out


def float_close(want: float, got: float, floor: float, rtol: float | None = RTOL) -> bool:
    """`got` is `want` within rtol of max(|want|, floor); NaN equals NaN. rtol None (a
    diverged or chaotic output): only the finiteness must agree."""
    if math.isnan(want) or math.isnan(got):
        return math.isnan(want) and math.isnan(got)
    if math.isinf(want) or math.isinf(got):
        return want == got
    return rtol is None or abs(got - want) <= rtol * max(abs(want), floor)


def _change(path: str, want: float, got: float, floor: float) -> str:
    ref = max(abs(want), floor)
    rel = abs(got - want) / ref if ref and math.isfinite(got - want) else math.inf
    return f"{path}: {want!r} -> {got!r} (relative {rel:.1e} of {ref:.3g})"


def _block_rtol(block: dict, rtol: float | None) -> float | None:
    """The tolerance for a JSON block's numbers: None (values not compared) once it
    recorded diverged runs, looser when its config runs sigma points with amplifying
    weights (see the module docstring)."""
    if rtol is None or any(_number(block.get(k)) and block[k] > 0 for k in DIVERGENCE_COUNTS):
        return None
    cfg = block.get("config")
    if isinstance(cfg, dict) and all(_number(cfg.get(k)) for k in ("alpha", "kappa", "L")):
        spread = cfg["alpha"] ** 2 * (cfg["L"] + cfg["kappa"])
        weight = abs(1 - cfg["L"] / spread) if spread else math.inf
        return max(RTOL, 100 * EPS * weight)     # this block's own sigma points
    return rtol


def json_differences(expected: object, got: object, path: str = "", floor: float = 0.0,
                     rtol: float | None = RTOL) -> list[str]:
    """Paths where `got` lacks or differs from a value of `expected` (floats within the
    tolerance above, everything else exactly; dictionaries in `got` may hold more keys)."""
    if isinstance(expected, dict):
        if not isinstance(got, dict):
            return [f"{path}: expected a mapping, got {got!r:.80}"]
        rtol = _block_rtol(expected, rtol)
        out = []
        for key, value in expected.items():
            if key not in got:
                out.append(f"{path}/{key}: missing")
                continue
            paired = re.fullmatch(r"(.+)_minus_.+", key)
            sibling = expected.get(paired.group(1)) if paired else None
            inner = max(floor, abs(sibling)) if _number(sibling) else floor
            out += json_differences(value, got[key], f"{path}/{key}", inner,
                                    None if key in CHAOTIC else rtol)
        return out
    if isinstance(expected, list):
        if not isinstance(got, list) or len(got) != len(expected):
            return [f"{path}: expected a list of {len(expected)}, got {got!r:.80}"]
        inner = max(floor, _magnitude(expected))
        return [d for i, (a, b) in enumerate(zip(expected, got))
                for d in json_differences(a, b, f"{path}[{i}]", inner, rtol)]
    if type(expected) is float and type(got) is float:
        return [] if float_close(expected, got, floor, rtol) else [
            _change(path, expected, got, floor)]
    if rtol is None and type(expected) is int and type(got) is int:
        count = path.rsplit("/", 1)[-1] in DIVERGENCE_COUNTS
        return [f"{path}: {expected!r} -> {got!r}"] if count and expected > 0 >= got else []
    if expected != got or type(expected) is not type(got):
        return [f"{path}: {expected!r} -> {got!r}"]
    return []


def _floats(row: list[str]) -> list[float | None]:
    """Each cell's value if it is written as a float (a decimal point, exponent, nan or
    inf), else None (an integer, an empty cell or text, which compare as text)."""
    out: list[float | None] = []
    for cell in row:
        try:
            out.append(float(cell) if any(c in cell.lower() for c in ".ein") else None)
        except ValueError:
            out.append(None)
    return out


def _estimate_floors(header: list[str], values: list[float | None]) -> list[float]:
    """Per cell of an ESTIMATES.csv row: x_i -> sqrt(P_ii), P_ij -> sqrt(P_ii P_jj)."""
    column = {name: j for j, name in enumerate(header)}

    def var(i: str) -> float:
        v = values[column[f"P{i}_{i}"]] if f"P{i}_{i}" in column else None
        return abs(v) if v is not None and math.isfinite(v) else 0.0

    floors = []
    for name in header:
        if m := re.fullmatch(r"x(\d+)", name):
            floors.append(math.sqrt(var(m[1])))
        elif m := re.fullmatch(r"P(\d+)_(\d+)", name):
            floors.append(math.sqrt(var(m[1]) * var(m[2])))
        else:
            floors.append(0.0)
    return floors


def _largest_variance(header: list[str], values: list[float | None]) -> float:
    out = 0.0
    for name, v in zip(header, values):
        if (m := re.fullmatch(r"P(\d+)_(\d+)", name)) and m[1] == m[2] and v is not None:
            out = max(out, abs(v))
    return out


def estimates_differences(expected: str, got: str, name: str = "", rtol: float = RTOL
                          ) -> list[str]:
    """Cells where `vtrack filter`'s ESTIMATES.csv text `got` differs from `expected`
    (floats within rtol as above, the rest exactly)."""
    want_rows = list(csv.reader(io.StringIO(expected)))
    got_rows = list(csv.reader(io.StringIO(got)))
    if len(got_rows) != len(want_rows):
        return [f"{name}: {len(want_rows)} rows expected, got {len(got_rows)}"]
    header = want_rows[0] if want_rows else []
    first = _largest_variance(header, _floats(want_rows[1])) if len(want_rows) > 1 else 0.0
    row_rtol: float | None = rtol
    out = []
    for i, (want, have) in enumerate(zip(want_rows, got_rows)):
        if len(have) != len(want):
            out.append(f"{name} row {i}: {len(want)} cells expected, got {have!r:.80}")
            continue
        wv, gv = _floats(want), _floats(have)
        if i and _largest_variance(header, wv) > DIVERGED * first:
            row_rtol = None               # diverged from here on
        floors = _estimate_floors(header, wv) if i else [0.0] * len(want)
        for j, (a, b) in enumerate(zip(want, have)):
            where = f"{name} row {i} column {header[j] if j < len(header) else j}"
            if wv[j] is None or gv[j] is None:
                if a != b:
                    out.append(f"{where}: {a!r} -> {b!r}")
            elif not float_close(wv[j], gv[j], floors[j], row_rtol):
                out.append(_change(where, wv[j], gv[j], floors[j]))
    return out
