"""What the set-up page edits, read from and written to CFG.toml and its CALIB.toml.

The page works on a *drawing*: every shape in pixels of the video's frame,

    {"width": W, "height": H,
     "lines":  [{"name": str, "points": [[x1, y1], [x2, y2]], "extra": {...}}],
     "gates":  [{"name": str, "line": [[x1, y1], [x2, y2]]} | {"name": str, "polygon": [...]}],
     "zones":  [{"name": str, "polygon": [[x, y], ...], "extra": {...}}],
     "roi":    [[x, y], ...] | None,
     "points": [{"image": [u, v], "world": [X, Y] | None}],
     "points_loaded": bool}   # the points came from the config's calibration file

(`extra`: the keys of an entry the page does not edit, e.g. a zone's `debounce_s`, kept as
they were). `load_drawing` turns a config (any units) into one; `save_drawing` merges one
into the config's parsed TOML, leaving every other key as it was, writes the shapes in
pixels, and writes the calibration points (those with road metres) as CALIB.toml. TOML
comments of an existing CFG.toml are not kept (tomllib reads no comments).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from vtrack.errors import InputError
from vtrack.fileio import read_toml, write_text
from vtrack.setup.toml_write import dumps

EDITED_KEYS = ("count_lines", "gates", "zones", "roi", "roi_units", "calibration")
PX_DECIMALS = 1   # shapes are saved to a tenth of a pixel


@dataclass(frozen=True)
class SetupFiles:
    """Where the page's work goes: CFG.toml and the CALIB.toml it names when points are
    placed (an existing `calibration` key keeps its file)."""

    config: Path
    calibration: Path

    @staticmethod
    def beside(config: Path, stem: str, existing: dict[str, Any]) -> SetupFiles:
        """CFG.toml `config`; CALIB.toml as the config names it, else STEM.calibration.toml
        in the config's folder."""
        named = existing.get("calibration")
        cal = (config.parent / named if isinstance(named, str) and named.strip()
               else config.parent / f"{stem}.calibration.toml")
        return SetupFiles(config, cal)


def read_config(path: Path) -> dict[str, Any]:
    """The parsed CFG.toml, or {} when it does not exist yet."""
    return read_toml(path) if path.exists() else {}


def _px(points: Any, units: str, width: int, height: int) -> list[list[float]]:
    scale = (width, height) if units == "fraction" else (1.0, 1.0)
    return [[float(p[0]) * scale[0], float(p[1]) * scale[1]] for p in points]


def _extra(entry: dict[str, Any], edited: tuple[str, ...]) -> dict[str, Any]:
    return {k: v for k, v in entry.items() if k not in edited}


def load_drawing(cfg: dict[str, Any], files: SetupFiles, width: int, height: int
                 ) -> dict[str, Any]:
    """The drawing of an existing config (checked first by the config reader, so shapes
    are well formed) and of its calibration file, if any."""
    from vtrack.app import config

    checkable = {k: v for k, v in cfg.items() if k != "gates" or _reader_knows_gates()}
    config.from_dict(checkable, str(files.config), files.config.parent)
    lines = []
    for k, entry in enumerate(cfg.get("count_lines", [])):
        if isinstance(entry, dict):
            pts = _px(entry["points"], entry.get("units", "px"), width, height)
            lines.append({"name": entry.get("name", f"line{k + 1}"), "points": pts,
                          "extra": _extra(entry, ("name", "points", "units"))})
        else:
            lines.append({"name": f"line{k + 1}", "points": [entry[:2], entry[2:]],
                          "extra": {}})
    gates = []
    for entry in cfg.get("gates", []):
        shape = "line" if "line" in entry else "polygon"
        gates.append({"name": entry.get("name", ""),
                      shape: _px(entry.get(shape, []), entry.get("units", "px"), width, height),
                      "extra": _extra(entry, ("name", "line", "polygon", "units"))})
    zones = [{"name": z["name"], "polygon": _px(z["polygon"], z.get("units", "px"), width,
                                               height),
              "extra": _extra(z, ("name", "polygon", "units"))} for z in cfg.get("zones", [])]
    roi = (_px(cfg["roi"], cfg.get("roi_units", "px"), width, height) if "roi" in cfg
           else None)
    points = []
    if "calibration" in cfg and files.calibration.exists():
        cal = read_toml(files.calibration)
        points = [{"image": p.get("image"), "world": p.get("world")}
                  for p in cal.get("points", []) if isinstance(p, dict)]
    return {"width": width, "height": height, "lines": lines, "gates": gates, "zones": zones,
            "roi": roi, "points": points, "points_loaded": bool(points)}


def _reader_knows_gates() -> bool:
    """Whether this version's config reader accepts [[gates]] (turning movements)."""
    from vtrack.app.config import AppConfig

    return "gates" in {f.name for f in dataclasses.fields(AppConfig)}


def _round(points: list[list[float]]) -> list[list[float]]:
    return [[round(float(x), PX_DECIMALS), round(float(y), PX_DECIMALS)] for x, y in points]


def merge_drawing(cfg: dict[str, Any], drawing: dict[str, Any], files: SetupFiles
                  ) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """(the new CFG.toml content, the CALIB.toml content or None): `cfg` with the edited
    keys replaced by the drawing's shapes (pixels), every other key kept."""
    out = {k: v for k, v in cfg.items() if k not in EDITED_KEYS}
    lines = [{"name": d["name"], "points": _round(d["points"]), "units": "px",
              **d.get("extra", {})} for d in drawing.get("lines", [])]
    if lines:
        out["count_lines"] = lines
    gates = []
    for d in drawing.get("gates", []):
        shape = "line" if d.get("line") else "polygon"
        gates.append({"name": d["name"], shape: _round(d[shape]), "units": "px",
                      **d.get("extra", {})})
    if gates:
        out["gates"] = gates
    zones = [{"name": d["name"], "polygon": _round(d["polygon"]), "units": "px",
              **d.get("extra", {})} for d in drawing.get("zones", [])]
    if zones:
        out["zones"] = zones
    if drawing.get("roi"):
        out["roi"] = _round(drawing["roi"])
        out["roi_units"] = "px"
    calibration = None
    placed = [p for p in drawing.get("points", []) if p.get("world") is not None]
    if placed:
        calibration = calibration_toml(placed, drawing["width"], drawing["height"])
        out["calibration"] = files.calibration.relative_to(files.config.parent).as_posix()
    elif "calibration" in cfg and not drawing.get("points_loaded"):
        out["calibration"] = cfg["calibration"]   # a file the page could not show: kept
    return out, calibration


def calibration_toml(points: list[dict[str, Any]], width: int, height: int) -> dict[str, Any]:
    """CALIB.toml content (INTERFACE.md): frame_size and [[points]] image / world."""
    return {"frame_size": [int(width), int(height)],
            "points": [{"image": _round([p["image"]])[0],
                        "world": [float(p["world"][0]), float(p["world"][1])]}
                       for p in points]}


def check_drawing(new_cfg: dict[str, Any], files: SetupFiles) -> None:
    """The new config as `vtrack track --config` will read it (InputError if it would
    refuse it); [[gates]] names are checked here when this version's reader has no gates."""
    from vtrack.app import config

    checkable = {k: v for k, v in new_cfg.items()
                 if k not in ("calibration", "gates") or (k == "gates" and _reader_knows_gates())}
    config.from_dict(checkable, str(files.config), files.config.parent)
    names = [g.get("name", "") for g in new_cfg.get("gates", [])]
    if any(not isinstance(n, str) or not n.strip() for n in names):
        raise InputError(f"{files.config}: every gate needs a name")
    if len(set(names)) != len(names):
        raise InputError(f"{files.config}: two gates have the same name")


def save_drawing(drawing: dict[str, Any], files: SetupFiles) -> list[Path]:
    """Merge the drawing into CFG.toml (re-read now, so edits made meanwhile are kept) and
    write it, and CALIB.toml when points were placed, atomically; returns the files
    written. InputError (nothing written) for a drawing the config reader would refuse."""
    new_cfg, calibration = merge_drawing(read_config(files.config), drawing, files)
    check_drawing(new_cfg, files)
    written = []
    if calibration is not None:
        files.calibration.parent.mkdir(parents=True, exist_ok=True)
        write_text(files.calibration, dumps(calibration))
        written.append(files.calibration)
    files.config.parent.mkdir(parents=True, exist_ok=True)
    write_text(files.config, dumps(new_cfg))
    written.append(files.config)
    return written
