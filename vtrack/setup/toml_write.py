"""A TOML writer for configs people read and edit: arrays (a polygon, a point) on one line,
tables and arrays of tables in blocks. Covers what tomllib returns for vtrack's files
(tables, arrays of tables, strings, numbers, booleans, arrays); `tomllib.loads(dumps(d))
== d` for such `d` (tests/setup/test_config_io.py)."""

from __future__ import annotations

import json
import math
import re
from typing import Any

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k)


def _value(v: Any) -> str:
    """A value on one line: TOML's basic strings share JSON's escapes."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _block(table: dict[str, Any], prefix: str, out: list[str]) -> None:
    """The plain keys of `table`, then its sub-tables and arrays of tables under `prefix`."""
    for k, v in table.items():
        if not isinstance(v, dict) and not _is_table_array(v):
            out.append(f"{_key(k)} = {_value(v)}")
    for k, v in table.items():
        name = f"{prefix}{_key(k)}"
        if isinstance(v, dict):
            out += ["", f"[{name}]"]
            _block(v, name + ".", out)
        elif _is_table_array(v):
            for entry in v:
                out += ["", f"[[{name}]]"]
                _block(entry, name + ".", out)


def dumps(data: dict[str, Any]) -> str:
    """TOML text of `data`."""
    out: list[str] = []
    _block(data, "", out)
    return "\n".join(out).lstrip("\n") + "\n"
