"""One registry of filter kinds and no import circle: vtrack.estimation (the generic core)
imports nothing of the packages built on it (vtrack.adaptive, vtrack.ins, ...); those add
their kinds to the core's registry, and vtrack.filter_kinds gathers them all."""

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import vtrack.estimation

CORE = Path(vtrack.estimation.__file__).parent
CORE_KINDS = {"kf", "ekf", "iekf", "ukf", "ckf", "iplf", "srukf", "crukf"}
ADAPTIVE_KINDS = {"ankf1", "ankf2", "fuzzy-r", "fuzzy-q", "siim-ekf"}


def _imports(path: Path) -> set[str]:
    """Every module a file imports, at the top or inside functions."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
    return out


def test_core_imports_only_itself_numpy_scipy_and_the_standard_library():
    allowed_roots = {"numpy", "scipy"} | set(sys.stdlib_module_names)
    for path in CORE.glob("*.py"):
        for mod in _imports(path):
            root = mod.split(".")[0]
            assert mod.startswith("vtrack.estimation") or root in allowed_roots, (path.name, mod)


def test_no_import_circle_in_the_core():
    graph = {p.stem: {m.rsplit(".", 1)[1] for m in _imports(p)
                      if m.startswith("vtrack.estimation.")} for p in CORE.glob("*.py")}
    done: set[str] = set()

    def visit(node: str, path: tuple[str, ...]) -> None:
        assert node not in path, " -> ".join(path + (node,))
        if node not in done:
            for nxt in graph.get(node, ()):
                visit(nxt, path + (node,))
            done.add(node)

    for node in graph:
        visit(node, ())


def test_importing_the_core_loads_no_package_built_on_it():
    """`python -c "import vtrack.estimation"` (and every core module) in a fresh interpreter:
    no module of vtrack.adaptive, vtrack.ins, the experiments or filter_kinds is loaded, and
    the registry holds exactly the core's kinds."""
    code = ("import importlib, pkgutil, sys, vtrack.estimation as e\n"
            "for m in pkgutil.iter_modules(e.__path__): importlib.import_module(f'{e.__name__}.{m.name}')\n"
            "from vtrack.estimation.registry import FILTER_KINDS\n"
            "print(sorted(FILTER_KINDS)); print(sorted(m for m in sys.modules if m.startswith('vtrack')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    kinds_line, modules_line = out.stdout.splitlines()
    assert set(eval(kinds_line)) == CORE_KINDS
    modules = eval(modules_line)
    assert all(m == "vtrack" or m.startswith("vtrack.estimation") for m in modules), modules


def test_filter_kinds_gathers_every_kind():
    from vtrack.estimation.models import WienerVelocity, position_measurement
    from vtrack.filter_kinds import FILTER_KINDS, make_filter

    assert set(FILTER_KINDS) == CORE_KINDS | ADAPTIVE_KINDS
    for kind in FILTER_KINDS:
        f = make_filter(kind, WienerVelocity(0.1), position_measurement(4, 0.1), np.zeros(4),
                        np.eye(4))
        assert f.kind == kind
    with pytest.raises(ValueError, match="unknown filter kind 'nope'.*iekf.*iplf"):
        make_filter("nope", WienerVelocity(0.1), position_measurement(4, 0.1), np.zeros(4),
                    np.eye(4))
