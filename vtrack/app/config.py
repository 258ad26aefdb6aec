"""The one TOML config of `vtrack track` / `vtrack batch`: every parameter, with documented
defaults (`vtrack config --defaults` prints them). Unknown sections or keys are errors.

    count_lines = [[x1, y1, x2, y2], {name, points, units}, ...]   # top level
    roi = [[x, y], ...], roi_units = "px"|"fraction"                 # top level, optional
    calibration = "CALIB.toml"    # top level, optional; relative to this file
    [[zones]] name, polygon, units, debounce_s                      # vtrack.analytics.regions
    [[gates]] name, line or polygon, units                          # vtrack.analytics.regions
    [detector] ...   vtrack.vision.detect.DetectorConfig
    [tracker]  ...   vtrack.tracking.tracker.TrackerConfig
    [output]   ...   OutputConfig
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from vtrack.analytics.regions import (ZONE_DEBOUNCE_S, CountLine, Gate, Roi, Zone,
                                      check_unique_names, parse_count_line, parse_gate,
                                      parse_roi,
                                      parse_zone)
from vtrack.errors import InputError
from vtrack.fileio import read_toml
from vtrack.tracking.config import TrackerConfig
from vtrack.vision.detect import DetectorConfig


@dataclass
class OutputConfig:
    """What the outputs look like ([output])."""

    trail_length: int = field(default=40, metadata={"help": "trail points drawn per track"})
    jpeg_quality: int = field(default=90, metadata={"help": "quality of --save-frames JPEGs"})
    rerun_image_width: int = field(default=640, metadata={
        "help": "video frames logged to rerun are downscaled to at most this width"})
    rerun_jpeg_quality: int = field(default=75, metadata={
        "help": "JPEG quality of the frames logged to rerun"})
    rerun_foreground: bool = field(default=False, metadata={
        "help": "also log the MOG2 foreground mask to rerun"})


@dataclass
class AppConfig:
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    output: OutputConfig = field(default_factory=OutputConfig)
    count_lines: list[CountLine] = field(default_factory=list)
    zones: list[Zone] = field(default_factory=list)
    roi: Roi | None = None            # the detector sees only inside this polygon
    calibration: str | None = None    # CALIB.toml (resolved against the config's folder)
    gates: list[Gate] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def digest(self) -> str:
        """sha256 of the effective config (recorded in summary.json)."""
        text = json.dumps(self.to_dict(), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


SECTIONS = {"detector": DetectorConfig, "tracker": TrackerConfig, "output": OutputConfig}
REGIONS = {"count_lines": parse_count_line, "zones": parse_zone, "gates": parse_gate}


def _coerce(where: str, value: Any, default: Any) -> Any:
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise InputError(f"{where} must be true or false")
        return value
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(f"{where} must be an integer")
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"{where} must be a number")
        return float(value)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise InputError(f"{where} must be a string")
        return value
    return value


SCALAR_KEYS = ("roi", "roi_units", "calibration")   # top-level keys besides REGIONS


def from_dict(data: dict[str, Any], source: str = "config",
              base: Path | None = None) -> AppConfig:
    """Build an AppConfig from parsed TOML; unknown keys and wrong types raise InputError.
    A relative `calibration` path is taken relative to `base` (the config file's folder)."""
    cfg = AppConfig()
    if "roi" in data:
        cfg.roi = parse_roi(f"{source}: roi", data["roi"], data.get("roi_units", "px"))
    elif "roi_units" in data:
        raise InputError(f"{source}: roi_units without roi")
    if "calibration" in data:
        path = data["calibration"]
        if not isinstance(path, str) or not path.strip():
            raise InputError(f"{source}: calibration must be the path of a CALIB.toml file")
        cfg.calibration = str(base / path if base is not None else Path(path))
    for key, value in data.items():
        if key in SCALAR_KEYS:
            continue
        if key in REGIONS:
            if not isinstance(value, list):
                raise InputError(f"{source}: {key} must be a list")
            setattr(cfg, key, [REGIONS[key](f"{source}: {key}[{k}]", v)
                               for k, v in enumerate(value)])
            continue
        if key not in SECTIONS:
            raise InputError(f"{source}: unknown key or section {key!r} "
                             f"(known: {', '.join([*REGIONS, *SCALAR_KEYS])}, "
                             f"{', '.join(SECTIONS)})")
        if not isinstance(value, dict):
            raise InputError(f"{source}: [{key}] must be a table")
        section = getattr(cfg, key)
        names = {f.name for f in dataclasses.fields(section)}
        for k, v in value.items():
            if k not in names:
                raise InputError(f"{source}: unknown key {k!r} in [{key}] "
                                 f"(known: {', '.join(sorted(names))})")
            setattr(section, k, _coerce(f"{source}: {key}.{k}", v, getattr(section, k)))
        validate = getattr(section, "validate", None)
        if validate is not None:
            try:
                validate()
            except ValueError as exc:
                raise InputError(f"{source}: {exc}") from None
    check_unique_names(source, cfg.count_lines, cfg.zones, cfg.gates)
    return cfg


def load(path: str | Path | None) -> AppConfig:
    """Read a TOML config file (None: the defaults)."""
    if path is None:
        return AppConfig()
    data = read_toml(path)
    return from_dict(data, str(path), Path(path).parent)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    return repr(v)


def defaults_toml() -> str:
    """The default config as documented TOML."""
    lines = ["# vtrack configuration: every key, with its default.",
             "# Counting lines (also --count-line): [x1, y1, x2, y2] in pixels, or tables",
             "# {name = \"north\", points = [[0, 0.6], [1, 0.6]], units = \"fraction\"}",
             "# (units \"px\" by default; a fraction of the width/height, 0..1).",
             "count_lines = []",
             *("# " + t for t in textwrap.wrap(
                 "Zones: [[zones]] tables with name, polygon = [[x, y], ...] (3+ vertices), "
                 "units = \"px\" | \"fraction\" and debounce_s (default "
                 f"{ZONE_DEBOUNCE_S}: {Zone.__dataclass_fields__['debounce_s'].metadata['help']}"
                 ").", 90)),
             "zones = []",
             "# Region of interest: the detector sees only inside this polygon (3+ vertices,",
             "# in roi_units \"px\" (default) or \"fraction\"); none: the whole frame.",
             "# roi = [[0, 0.4], [1, 0.4], [1, 1], [0, 1]]",
             "# roi_units = \"fraction\"",
             "# Ground-plane calibration (CALIB.toml, a path relative to this file); "
             "--calibration",
             "# overrides it.",
             "# calibration = \"site.calibration.toml\"",
             *("# " + t for t in textwrap.wrap(
                 "Gates of the turning movements (movements.csv): [[gates]] tables with name, "
                 "line = [[x1, y1], [x2, y2]] or polygon = [[x, y], ...], and units = \"px\" | "
                 "\"fraction\". A track passes a gate when its box centre's path crosses the "
                 "line or enters the polygon; one that passes two or more gates makes one "
                 "movement, from its first gate to its last.", 90)),
             "gates = []", ""]
    cfg = AppConfig()
    for name, cls in SECTIONS.items():
        lines.append(f"[{name}]")
        doc = (cls.__doc__ or "").strip().splitlines()
        if doc:
            lines.insert(len(lines) - 1, f"# {doc[0]}")
        for f in dataclasses.fields(cls):
            help_ = f.metadata.get("help", "")
            if help_:
                lines.append(f"# {help_}")
            lines.append(f"{f.name} = {_toml_value(getattr(getattr(cfg, name), f.name))}")
        lines.append("")
    return "\n".join(lines)
