"""`vtrack report RUN_DIR`: one self-contained HTML page summarising a `vtrack track` run.

Reads summary.json and tracks.csv (required) and counts.csv, vehicles.csv, zone_events.csv,
movements.csv and speeds.csv (when the run wrote them); writes RUN_DIR/report.html atomically. Charts are inline SVG and
the first frame is a base64 JPEG inside the SVG, so the page needs no network. The first
frame comes from frames/000001.jpg (--save-frames), else from the video named in
summary.json, else the tracks are drawn on a blank canvas of the video's size (the page says
which).
"""

from __future__ import annotations

import base64
import csv
import json
import math
from collections import defaultdict
from dataclasses import dataclass
from html import escape
from pathlib import Path
from typing import Any

import numpy as np

from vtrack.errors import InputError
from vtrack.fileio import open_input, write_text
from vtrack.report.svg import bar_chart, legend, track_map

CLASS_COLOURS = {"motorcycle": "#9b51e0", "bicycle": "#27ae60", "car": "#2f80ed",
                 "van": "#f2994a", "bus": "#f2c94c", "truck": "#eb5757", "unknown": "#9aa3ad",
                 "all": "#2f80ed"}
MAX_TRACKS_DRAWN = 3000
POINTS_PER_TRACK = 80
SPEED_BIN_KMH = 10


@dataclass
class Run:
    """The files of one run, as read."""

    dir: Path
    summary: dict[str, Any]
    counts: list[dict] | None
    vehicles: list[dict] | None
    zone_events: list[dict] | None
    movements: list[dict] | None = None
    speeds: list[dict] | None = None

    @property
    def calibrated(self) -> bool:
        return self.summary.get("calibration") is not None


def _read_csv(path: Path) -> list[dict] | None:
    if not path.exists():
        return None
    with open_input(path, "CSV file", newline="", encoding="utf-8") as fh:
        try:
            return list(csv.DictReader(fh))
        except (csv.Error, UnicodeDecodeError) as exc:
            raise InputError(f"{path}: malformed CSV ({exc})") from None


def load_run(run_dir: str | Path) -> Run:
    """Read a run folder; InputError when it is not one (no summary.json or tracks.csv)."""
    d = Path(run_dir)
    if not d.is_dir():
        raise InputError(f"{d}: not a folder (expected the output folder of vtrack track)")
    for name in ("summary.json", "tracks.csv"):
        if not (d / name).is_file():
            raise InputError(f"{d}: no {name} (not the output folder of vtrack track)")
    with open_input(d / "summary.json", "JSON file", encoding="utf-8") as fh:
        try:
            summary = json.load(fh)
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"{d / 'summary.json'}: malformed JSON ({exc})") from None
    need = ("video", "frames", "width", "height", "fps_video", "tracks", "counts")
    if not isinstance(summary, dict) or any(k not in summary for k in need):
        raise InputError(f"{d / 'summary.json'}: missing keys of a run summary "
                         f"({', '.join(need)})")
    return Run(d, summary, _read_csv(d / "counts.csv"), _read_csv(d / "vehicles.csv"),
               _read_csv(d / "zone_events.csv"), _read_csv(d / "movements.csv"),
               _read_csv(d / "speeds.csv"))


# ----------------------------------------------------------------------------- helpers

def _clock(seconds: float, with_hours: bool) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s % 3600 // 60:02d}" if with_hours else f"{s // 60}:{s % 60:02d}"


def _duration(seconds: float) -> str:
    s = round(seconds)
    if s < 60:
        return f"{seconds:g} s"
    if s < 3600:
        return f"{s // 60} min" + (f" {s % 60:02d} s" if s % 60 else "")
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def _num(text: str | None) -> float:
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def _v85(values: list[float]) -> float:
    return float(np.percentile(values, 85)) if values else math.nan


def _f(v: float, d: int = 1) -> str:
    return f"{v:.{d}f}" if math.isfinite(v) else "–"


def _table(head: list[str], rows: list[list[Any]], cls: str = "") -> str:
    h = "".join(f"<th>{escape(str(c))}</th>" for c in head)
    b = "".join("<tr>" + "".join(f"<td>{escape(str(c))}</td>" for c in r) + "</tr>"
                for r in rows)
    return f'<table class="{cls}"><thead><tr>{h}</tr></thead><tbody>{b}</tbody></table>'


def _classes(run: Run) -> list[str]:
    seen = {r["class"] for r in run.counts or []}
    order = [c for c in CLASS_COLOURS if c in seen]
    return order + sorted(seen - set(order))


# ----------------------------------------------------------------------------- sections

def _header(run: Run) -> str:
    s = run.summary
    fps = s["fps_video"] or 25.0
    duration = s["frames"] / fps
    facts = [("video", Path(s["video"]).name), ("duration", _duration(duration)),
             ("frames", s["frames"]), ("frame size", f"{s['width']}x{s['height']}")]
    if "bin_seconds" in s:
        facts.append(("time bin", _duration(s["bin_seconds"])))
    facts.append(("calibration", _calibration_fact(s.get("calibration"))))
    if not s.get("complete", True):
        facts.append(("run", "incomplete (interrupted)"))
    items = "".join(f"<div><dt>{escape(k)}</dt><dd>{escape(str(v))}</dd></div>" for k, v in facts)
    return (f"<header><h1>Traffic report</h1><p class=sub>{escape(Path(s['video']).name)}</p>"
            f"<dl class=facts>{items}</dl></header>")


def _calibration_fact(cal: dict | None) -> str:
    """The calibration's points and reprojection error (mean / max, px and m)."""
    if not cal:
        return "none (no speeds or classes)"
    px, m = cal.get("reprojection_px"), cal.get("reprojection_m")
    if not (px and m):                       # a summary of an older run: RMS only
        return f"{cal['points']} points, {cal['reprojection_rms_px']:.2f} px RMS"
    return (f"{cal['points']} points, reprojection error mean {px['mean']:.2f} px / "
            f"{m['mean']:.2f} m, max {px['max']:.2f} px / {m['max']:.2f} m")


def _cards(run: Run) -> str:
    s = run.summary
    vehicles = run.vehicles or []
    crossings = sum(int(c["total"]) for c in s["counts"])
    cards = [("vehicles tracked", str(len(vehicles) if run.vehicles is not None else s["tracks"])),
             ("line crossings", str(crossings))]
    if run.calibrated:
        speeds = [v for v in (_num(r["speed_mean_kmh"]) for r in vehicles) if math.isfinite(v)]
        cards.append(("mean speed", f"{_f(float(np.mean(speeds)) if speeds else math.nan)} km/h"))
        cards.append(("85th percentile speed", f"{_f(_v85(speeds))} km/h"))
        mix = defaultdict(int)
        for r in vehicles:
            mix[r["class"] or "unknown"] += 1
        if vehicles:
            cards.append(("class mix", " · ".join(
                f"{c} {100 * n / len(vehicles):.0f}%" for c, n in
                sorted(mix.items(), key=lambda kv: -kv[1]))))
    return '<div class="cards">' + "".join(
        f'<div class="card"><div class="k">{escape(k)}</div><div class="v'
        f'{" small" if len(v) > 14 else ""}">{escape(v)}</div></div>' for k, v in cards) + "</div>"


def _counts_section(run: Run) -> str:
    if run.counts is None:
        return ('<section id="counts"><h2>Counts per time bin</h2><p class=note>This run has '
                'no counts.csv.</p></section>')
    if not run.summary["counts"]:
        return ('<section id="counts"><h2>Counts per time bin</h2><p class=note>No counting '
                'lines were set (--count-line or count_lines in the config).</p></section>')
    classes = _classes(run)
    starts, labels = _bin_labels(run.counts)
    idx = {t: i for i, t in enumerate(starts)}
    grid: dict[tuple[str, str, str], list[float]] = defaultdict(lambda: [0.0] * len(starts))
    for r in run.counts:
        grid[(r["line"], r["direction"], r["class"])][idx[_num(r["bin_start_s"])]] += int(
            r["count"])
    lines = list(dict.fromkeys(r["line"] for r in run.counts))
    charts, rows = [], []
    for line in lines:
        for direction in ("forward", "backward"):
            series = [(c, CLASS_COLOURS.get(c, "#777"), grid[(line, direction, c)])
                      for c in classes]
            total = sum(sum(v) for _, _, v in series)
            chart = bar_chart(labels, series, width=470, height=190,
                              title=f"line {line} · {direction} · {int(total)} vehicles",
                              y_label="vehicles per bin")
            charts.append(f"<figure>{chart}</figure>")
            rows.append([line, direction] + [int(sum(grid[(line, direction, c)]))
                                              for c in classes] + [int(total)])
    lg = legend([(c, CLASS_COLOURS.get(c, "#777")) for c in classes]) if len(classes) > 1 else ""
    return (f'<section id="counts"><h2>Counts per time bin</h2>{lg}'
            f'<div class="charts">{"".join(charts)}</div>'
            + _table(["line", "direction"] + classes + ["total"], rows, "counts-table")
            + "</section>")


def _speed_section(run: Run) -> str:
    if not run.calibrated or not run.vehicles:
        why = ("the run has no calibration (vtrack track --calibration CALIB.toml)"
               if not run.calibrated else "no vehicles were tracked")
        return (f'<section id="speeds"><h2>Speeds per class</h2><p class=note>No speeds: '
                f'{escape(why)}.</p></section>')
    by_class: dict[str, list[dict]] = defaultdict(list)
    for r in run.vehicles:
        by_class[r["class"] or "unknown"].append(r)
    classes = [c for c in CLASS_COLOURS if c in by_class]
    speeds = {c: [v for v in (_num(r["speed_mean_kmh"]) for r in by_class[c])
                  if math.isfinite(v)] for c in classes}
    every = [v for sp in speeds.values() for v in sp] or [0.0]
    lo = SPEED_BIN_KMH * math.floor(min(every) / SPEED_BIN_KMH)
    hi = SPEED_BIN_KMH * (math.floor(max(every) / SPEED_BIN_KMH) + 1)
    edges = np.arange(lo, hi + SPEED_BIN_KMH / 2, SPEED_BIN_KMH)
    labels = [f"{a:g}–{b:g}" for a, b in zip(edges[:-1], edges[1:])]
    series = [(c, CLASS_COLOURS[c], np.histogram(speeds[c], edges)[0].tolist()) for c in classes]
    chart = bar_chart(labels, series, width=640, height=210, y_label="vehicles",
                      title="vehicles by mean speed, km/h",
                      max_labels=16)
    rows = []
    for c in classes:
        sp = speeds[c]
        mx = [v for v in (_num(r["speed_max_kmh"]) for r in by_class[c]) if math.isfinite(v)]
        ln = [v for v in (_num(r["length_m"]) for r in by_class[c]) if math.isfinite(v)]
        rows.append([c, len(by_class[c]), _f(float(np.mean(sp)) if sp else math.nan),
                     _f(_v85(sp)), _f(max(mx) if mx else math.nan),
                     _f(float(np.mean(ln)) if ln else math.nan, 2)])
    return ('<section id="speeds"><h2>Speeds per class</h2>'
            + legend([(c, CLASS_COLOURS[c]) for c in classes])
            + f"<figure>{chart}</figure>"
            + _table(["class", "vehicles", "mean speed km/h", "85th percentile km/h",
                      "max speed km/h", "mean length m"], rows, "speed-table")
            + "</section>")


def _bin_labels(rows: list[dict]) -> tuple[list[float], list[str]]:
    """The bins' start times and their clock labels (h:mm for long runs or bins, else m:ss)."""
    starts = sorted({_num(r["bin_start_s"]) for r in rows})
    with_hours = max(starts, default=0) >= 3600 or (
        len(starts) > 1 and starts[1] - starts[0] >= 600)
    return starts, [_clock(t, with_hours) for t in starts]


def _line_speed_section(run: Run) -> str:
    """The 85th-percentile speed at each count line per bin and direction (speeds.csv)."""
    head = '<section id="p85"><h2>Speeds at the count lines per time bin</h2>'
    if run.speeds is None or not run.calibrated or not run.summary["counts"]:
        why = ("the run has no speeds.csv" if run.speeds is None else
               "the run has no calibration (vtrack track --calibration CALIB.toml)"
               if not run.calibrated else "no counting lines were set")
        return f"{head}<p class=note>No speeds at the lines: {escape(why)}.</p></section>"
    rows = [r for r in run.speeds if r["class"] == "all"]
    starts, labels = _bin_labels(rows)
    idx = {t: i for i, t in enumerate(starts)}
    p85: dict[tuple[str, str], list[float]] = defaultdict(lambda: [math.nan] * len(starts))
    for r in rows:
        p85[(r["line"], r["direction"])][idx[_num(r["bin_start_s"])]] = _num(r["p85_kmh"])
    charts, table = [], []
    for (line, direction), values in p85.items():
        if not any(math.isfinite(v) for v in values):
            continue
        chart = bar_chart(labels, [("p85", "#2f80ed", [v if math.isfinite(v) else 0.0
                                                       for v in values])],
                          width=470, height=190, y_label="km/h",
                          title=f"line {line} · {direction} · 85th percentile speed")
        charts.append(f"<figure>{chart}</figure>")
    for r in rows:
        if int(r["count"]):
            table.append([labels[idx[_num(r["bin_start_s"])]], r["line"], r["direction"],
                          r["count"], r["mean_kmh"], r["p50_kmh"], r["p85_kmh"], r["max_kmh"]])
    if not table:
        return (f"{head}<p class=note>No vehicle with a measured speed crossed a counting "
                f"line.</p></section>")
    return (head + f'<div class="charts">{"".join(charts)}</div>'
            + _table(["bin", "line", "direction", "vehicles", "mean km/h", "p50 km/h",
                      "p85 km/h", "max km/h"], table, "p85-table")
            + "<p class=note>The speed of each vehicle as it crosses the line (the road "
              "distance its filtered ground point covers in the second around the crossing), "
              "all classes; speeds.csv has them per class. A bin without a crossing in a "
              "direction has no bar.</p>"
            + "</section>")


def _movements_section(run: Run) -> str:
    """The origin-destination matrix of the turning movements (summary.json `movements`)."""
    head = '<section id="movements"><h2>Turning movements</h2>'
    gates = [g["name"] for g in run.summary.get("gates") or []]
    moves = run.summary.get("movements") or []
    if len(gates) < 2:
        return (f"{head}<p class=note>No turning movements: they need two or more gates "
                f"([[gates]] in the config).</p></section>")
    n = {(m["from"], m["to"]): int(m["count"]) for m in moves}
    top = max(n.values(), default=0) or 1
    cells = []
    for a in gates:
        row = [f"<th>{escape(a)}</th>"]
        for b in gates:
            if a == b:
                row.append('<td class="diag">–</td>')
                continue
            v = n.get((a, b), 0)
            row.append(f'<td style="background:rgba(47,128,237,{0.08 + 0.6 * v / top:.2f})">'
                       f"{v}</td>")
        row.append(f"<td><b>{sum(n.get((a, b), 0) for b in gates)}</b></td>")
        cells.append("<tr>" + "".join(row) + "</tr>")
    foot = ("<tr><th>total in</th>" + "".join(
        f"<td><b>{sum(n.get((a, b), 0) for a in gates)}</b></td>" for b in gates)
        + f"<td><b>{sum(n.values())}</b></td></tr>")
    table = ('<table class="od-table"><thead><tr><th>from \\ to</th>'
             + "".join(f"<th>{escape(b)}</th>" for b in gates)
             + "<th>total out</th></tr></thead><tbody>" + "".join(cells) + foot
             + "</tbody></table>")
    by_class = ""
    if run.movements and run.calibrated:
        per: dict[tuple[str, str], dict[str, int]] = defaultdict(lambda: defaultdict(int))
        for r in run.movements:
            per[(r["from"], r["to"])][r["class"]] += int(r["count"])
        classes = [c for c in CLASS_COLOURS if any(per[k].get(c) for k in per)]
        rows = [[a, b] + [per[(a, b)].get(c, 0) for c in classes] + [n.get((a, b), 0)]
                for a in gates for b in gates if a != b and n.get((a, b), 0)]
        if rows and classes:
            by_class = _table(["from", "to"] + classes + ["total"], rows, "movement-table")
    return (head + table + by_class
            + "<p class=note>Vehicles per origin gate (rows) and destination gate (columns): "
              "a vehicle's first and last gate passed (its box centre crossing the gate's "
              "line or entering its polygon); movements.csv has them per time bin.</p>"
            + "</section>")


def _first_frame(run: Run) -> tuple[str | None, str]:
    """(data URI of a JPEG, where it came from)."""
    import cv2

    jpg = run.dir / "frames" / "000001.jpg"
    if jpg.is_file():
        img = cv2.imread(str(jpg))
        if img is not None:
            return _jpeg_uri(img), "the first annotated frame (frames/000001.jpg)"
    video = Path(run.summary["video"])
    if not video.is_absolute() and not video.exists():
        video = run.dir / video
    try:
        from vtrack.io.video import VideoReader

        with VideoReader(video, max_frames=1) as reader:
            frame = next(iter(reader), None)
        if frame is not None:
            return _jpeg_uri(frame.image), f"the first frame of {video.name}"
    except (InputError, OSError):
        pass
    return None, (f"a blank canvas of the video's size ({video.name} is not readable here "
                  f"and the run has no frames/000001.jpg)")


def _jpeg_uri(img: np.ndarray, max_width: int = 960) -> str:
    import cv2

    h, w = img.shape[:2]
    if w > max_width:
        img = cv2.resize(img, (max_width, round(h * max_width / w)), interpolation=cv2.INTER_AREA)
    ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 82])
    return "data:image/jpeg;base64," + base64.b64encode(data.tobytes()).decode("ascii")


def _paths(run: Run) -> tuple[list[tuple[str, list[tuple[float, float]]]], int]:
    """Box-centre paths of the first MAX_TRACKS_DRAWN tracks (thinned to POINTS_PER_TRACK
    points) coloured by class; and how many tracks there were."""
    pts: dict[int, list[tuple[float, float]]] = defaultdict(list)
    ids: set[int] = set()
    with open_input(run.dir / "tracks.csv", "CSV file", newline="") as fh:
        for row in csv.reader(fh):
            try:
                tid = int(float(row[1]))
                x, y, w, h = (float(v) for v in row[2:6])
            except (ValueError, IndexError):
                raise InputError(f"{run.dir / 'tracks.csv'}: malformed row {row[:6]}") from None
            ids.add(tid)
            if tid in pts or len(pts) < MAX_TRACKS_DRAWN:
                pts[tid].append((x + w / 2, y + h / 2))
    cls = {int(r["id"]): (r["class"] or "unknown") for r in run.vehicles or []}
    out = []
    palette = ["#2f80ed", "#27ae60", "#f2c94c", "#eb5757", "#9b51e0", "#56ccf2", "#f2994a"]
    for tid, p in pts.items():
        step = max(1, math.ceil(len(p) / POINTS_PER_TRACK))
        thin = p[::step] + ([p[-1]] if (len(p) - 1) % step else [])
        colour = (CLASS_COLOURS.get(cls.get(tid, ""), "#9aa3ad") if run.calibrated
                  else palette[tid % len(palette)])
        out.append((colour, thin))
    return out, len(ids)


def _map_section(run: Run) -> str:
    s = run.summary
    uri, source = _first_frame(run)
    paths, n = _paths(run)
    lines = [(c.get("name", str(k)), c["line"]) for k, c in enumerate(s["counts"])]
    zones = [(z["name"], z["polygon"]) for z in s.get("zones") or [] if z.get("polygon")]
    gates = [(f"gate {g['name']}", g.get("line") or g["polygon"]) for g in s.get("gates") or []]
    svg = track_map(s["width"], s["height"], uri, paths, lines, zones, gates=gates)
    shown = f"all {n} tracks" if n <= MAX_TRACKS_DRAWN else f"the first {MAX_TRACKS_DRAWN} of {n}"
    note = (f"Box-centre paths of {shown}"
            + (", coloured by class" if run.calibrated else "")
            + f", counting lines (yellow), zones (cyan) and gates (dashed orange) over {source}.")
    lg = legend([(c, CLASS_COLOURS[c]) for c in ("motorcycle", "car", "van", "truck")]) \
        if run.calibrated else ""
    return (f'<section id="map"><h2>Tracks</h2>{lg}<figure class="map">{svg}</figure>'
            f"<p class=note>{escape(note)}</p></section>")


def _zones_section(run: Run) -> str:
    zones = run.summary.get("zones") or []
    if not zones:
        return ('<section id="zones"><h2>Zones</h2><p class=note>No zones were set '
                '([[zones]] in the config).</p></section>')
    events = run.zone_events or []
    rows = []
    for z in zones:
        ev = [e for e in events if e["zone"] == z["name"]]
        dwell = [_num(e["dwell_s"]) for e in ev]
        inside = sum(e["exit_frame"] == "" for e in ev)
        rows.append([z["name"], z["entries"], z["max_occupancy"], _f(z["mean_dwell_s"], 2),
                     _f(float(np.median(dwell)) if dwell else math.nan, 2),
                     _f(max(dwell) if dwell else math.nan, 2), inside])
    return ('<section id="zones"><h2>Zones</h2>'
            + _table(["zone", "entries", "max occupancy", "mean dwell s", "median dwell s",
                      "longest dwell s", "no exit seen"], rows, "zone-table")
            + '<p class=note>A vehicle is in a zone while the bottom centre of its box (where it '
              'meets the road) is inside; "no exit seen": still inside when its track ended.'
              "</p></section>")


CSS = """
*{box-sizing:border-box}body{margin:0;background:#f4f6f8;color:#2d3640;
font:14px/1.45 system-ui,-apple-system,'Segoe UI',Roboto,sans-serif}
main{max-width:1080px;margin:0 auto;padding:24px 28px 40px}
header h1{margin:0;font-size:26px}header .sub{margin:2px 0 12px;color:#6b7785}
.facts{display:flex;flex-wrap:wrap;gap:6px 22px;margin:0}.facts div{display:flex;gap:6px}
.facts dt{color:#6b7785}.facts dd{margin:0;font-weight:600}
.cards{display:grid;grid-template-columns:repeat(auto-fit,minmax(170px,1fr));gap:12px;margin:18px 0}
.card{background:#fff;border-radius:10px;padding:12px 14px;box-shadow:0 1px 2px #0001}
.card .k{color:#6b7785;font-size:12px;text-transform:uppercase;letter-spacing:.04em}
.card .v{font-size:22px;font-weight:650;margin-top:2px}.card .v.small{font-size:14px;
font-weight:600;line-height:1.5}
section{background:#fff;border-radius:10px;padding:16px 18px;margin:14px 0;box-shadow:0 1px 2px #0001}
h2{font-size:17px;margin:0 0 10px}.charts{display:grid;grid-template-columns:repeat(2,470px);
gap:6px 28px}
figure{margin:0}
.map svg{border-radius:6px;display:block}
table{border-collapse:collapse;margin-top:10px;font-variant-numeric:tabular-nums}
th,td{padding:5px 12px;text-align:right;border-bottom:1px solid #e8ebef}
th:first-child,td:first-child{text-align:left}th{color:#6b7785;font-weight:600;font-size:12px}
.od-table td{text-align:center;min-width:64px}.od-table td.diag{color:#c0c6cc}
.legend{display:flex;gap:14px;margin:0 0 8px;font-size:12px;color:#4a5561}
.legend i{display:inline-block;width:11px;height:11px;border-radius:2px;margin-right:5px;
vertical-align:-1px}.note{color:#6b7785;font-size:12.5px;margin:8px 0 0}
footer{color:#8a949e;font-size:12px;text-align:center}
"""


def render(run: Run) -> str:
    """The report page of a run."""
    s = run.summary
    body = (_header(run) + _cards(run) + _counts_section(run) + _line_speed_section(run)
            + _speed_section(run) + _movements_section(run) + _map_section(run)
            + _zones_section(run))
    foot = (f"<footer>vtrack {escape(str(s.get('vtrack_version', '')))} · from summary.json, "
            f"tracks.csv, counts.csv, speeds.csv, movements.csv, vehicles.csv and "
            f"zone_events.csv in "
            f"{escape(run.dir.name)}/</footer>")
    return ("<!DOCTYPE html><html lang=en><head><meta charset=utf-8>"
            f"<meta name=viewport content='width=device-width,initial-scale=1'>"
            f"<title>Traffic report – {escape(Path(s['video']).name)}</title>"
            f"<style>{CSS}</style></head><body><main>{body}{foot}</main></body></html>\n")


def write_report(run_dir: str | Path) -> Path:
    """Write RUN_DIR/report.html (atomically); returns its path."""
    run = load_run(run_dir)
    path = run.dir / "report.html"
    write_text(path, render(run))
    return path
