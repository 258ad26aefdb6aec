"""Validation of filter options (numbers and flags from make_filter's keywords or a TOML
[filter] table), with errors that name the option."""

from __future__ import annotations

import numpy as np


def _is_number(value: object) -> bool:
    return (not isinstance(value, (bool, np.bool_))
            and isinstance(value, (int, float, np.integer, np.floating)))


def int_option(name: str, value: object, lo: int) -> int:
    """An integer >= lo (an integral float such as 10.0 is accepted)."""
    if not _is_number(value) or not np.isfinite(value) or not float(value).is_integer() \
            or value < lo:
        raise ValueError(f"option {name} must be an integer >= {lo} (got {value!r})")
    return int(value)


def float_option(name: str, value: object, lo: float | None = None, strict: bool = True
                 ) -> float:
    """A finite number, > lo (strict) or >= lo when lo is given."""
    ok = _is_number(value) and np.isfinite(value)
    if ok and lo is not None:
        ok = value > lo if strict else value >= lo
    if not ok:
        bound = "" if lo is None else f" {'>' if strict else '>='} {lo:g}"
        raise ValueError(f"option {name} must be a finite number{bound} (got {value!r})")
    return float(value)


def bool_option(name: str, value: object) -> bool:
    """true or false (or 1 / 0)."""
    if isinstance(value, (bool, np.bool_)) or (_is_number(value) and value in (0, 1)):
        return bool(value)
    raise ValueError(f"option {name} must be true or false (got {value!r})")
