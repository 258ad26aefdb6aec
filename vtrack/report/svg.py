"""Inline SVG charts for the run report: a stacked bar chart (counts per bin, speed histogram)
and a map of tracks over an image. Plain strings, no plotting library, no network."""

from __future__ import annotations

import math
from collections.abc import Sequence
from html import escape

FONT = "font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif"
AXIS, GRID, TEXT = "#9aa3ad", "#e8ebef", "#3b4450"


def nice_ticks(top: float, count: int = 4) -> list[float]:
    """Round tick values 0 .. >= top (steps of 1, 2 or 5 times a power of ten)."""
    if top <= 0:
        return [0.0, 1.0]
    raw = top / count
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    if step < 1 and top >= 1:
        step = 1.0
    n = math.ceil(top / step - 1e-9)
    return [round(i * step, 10) for i in range(n + 1)]


def _fmt(v: float) -> str:
    return f"{v:g}"


def bar_chart(categories: Sequence[str], series: Sequence[tuple[str, str, Sequence[float]]],
              width: int = 520, height: int = 200, y_label: str = "",
              title: str = "", max_labels: int = 10) -> str:
    """Stacked bars: one bar per category, one coloured segment per series (name, colour,
    values). Returns an <svg> element."""
    left, right, top, bottom = 44, 10, 26 if title else 10, 34
    pw, ph = width - left - right, height - top - bottom
    totals = [sum(s[2][i] for s in series) for i in range(len(categories))]
    ticks = nice_ticks(max(totals, default=0))
    ymax = ticks[-1]
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'viewBox="0 0 {width} {height}" style="{FONT}" role="img" '
           f'aria-label="{escape(title or y_label)}">']
    if title:
        out.append(f'<text x="{left}" y="16" font-size="13" font-weight="600" '
                   f'fill="{TEXT}">{escape(title)}</text>')
    for t in ticks:
        y = top + ph - ph * t / ymax
        out.append(f'<line x1="{left}" x2="{left + pw}" y1="{y:.1f}" y2="{y:.1f}" '
                   f'stroke="{GRID}"/>')
        out.append(f'<text x="{left - 6}" y="{y + 4:.1f}" font-size="11" text-anchor="end" '
                   f'fill="{AXIS}">{_fmt(t)}</text>')
    if y_label:
        out.append(f'<text transform="translate(11,{top + ph / 2:.0f}) rotate(-90)" '
                   f'font-size="11" text-anchor="middle" fill="{AXIS}">{escape(y_label)}</text>')
    n = max(len(categories), 1)
    slot = pw / n
    bar = max(1.0, slot * 0.78)
    every = max(1, math.ceil(n / max_labels))
    for i, cat in enumerate(categories):
        x = left + i * slot + (slot - bar) / 2
        y = top + ph
        for name, colour, values in series:
            v = values[i]
            if v <= 0:
                continue
            h = ph * v / ymax
            y -= h
            out.append(f'<rect x="{x:.1f}" y="{y:.1f}" width="{bar:.1f}" height="{h:.1f}" '
                       f'fill="{colour}"><title>{escape(cat)}: {escape(name)} '
                       f'{_fmt(v)}</title></rect>')
        if i % every == 0:
            out.append(f'<text x="{x + bar / 2:.1f}" y="{top + ph + 14}" font-size="10" '
                       f'text-anchor="middle" fill="{AXIS}">{escape(cat)}</text>')
    out.append(f'<line x1="{left}" x2="{left + pw}" y1="{top + ph}" y2="{top + ph}" '
               f'stroke="{AXIS}"/>')
    out.append("</svg>")
    return "".join(out)


def legend(items: Sequence[tuple[str, str]]) -> str:
    """An HTML legend: coloured swatches with names."""
    return '<div class="legend">' + "".join(
        f'<span><i style="background:{c}"></i>{escape(n)}</span>' for n, c in items) + "</div>"


def track_map(width: int, height: int, image_data_uri: str | None,
              paths: Sequence[tuple[str, Sequence[tuple[float, float]]]],
              lines: Sequence[tuple[str, Sequence[float]]],
              zones: Sequence[tuple[str, Sequence[Sequence[float]]]],
              display_width: int = 960,
              gates: Sequence[tuple[str, Sequence[Sequence[float]]]] = ()) -> str:
    """The image (or a blank canvas of its size) with track paths (colour, points), counting
    lines (label, [x1, y1, x2, y2]), zones (label, polygon) and gates (label, two points of a
    line or a polygon's vertices; dashed orange, labelled at their middle) in image
    pixels."""
    s = max(width, height) / 640.0                 # stroke and font scale in image pixels
    dh = round(display_width * height / width)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{display_width}" height="{dh}" '
           f'viewBox="0 0 {width} {height}" style="{FONT};max-width:100%;height:auto" '
           f'role="img" aria-label="tracks over the first frame">']
    if image_data_uri:
        out.append(f'<image href="{image_data_uri}" x="0" y="0" width="{width}" '
                   f'height="{height}" preserveAspectRatio="none"/>')
        out.append(f'<rect width="{width}" height="{height}" fill="#000" opacity="0.25"/>')
    else:
        out.append(f'<rect width="{width}" height="{height}" fill="#2b3138"/>')
    for colour, pts in paths:
        if len(pts) > 1:
            d = " ".join(f"{x:.1f},{y:.1f}" for x, y in pts)
            out.append(f'<polyline points="{d}" fill="none" stroke="{colour}" '
                       f'stroke-width="{1.6 * s:.2f}" stroke-opacity="0.8" '
                       f'stroke-linejoin="round" stroke-linecap="round"/>')
    for label, poly in zones:
        d = " ".join(f"{x:.1f},{y:.1f}" for x, y in poly)
        x0, y0 = poly[0]
        out.append(f'<polygon points="{d}" fill="#00e5ff" fill-opacity="0.18" stroke="#00e5ff" '
                   f'stroke-width="{2 * s:.2f}"/>')
        out.append(_label(label, x0, y0, "#00e5ff", s))
    for label, (x1, y1, x2, y2) in lines:
        out.append(f'<line x1="{x1:.1f}" y1="{y1:.1f}" x2="{x2:.1f}" y2="{y2:.1f}" '
                   f'stroke="#ffe14d" stroke-width="{3 * s:.2f}" stroke-linecap="round"/>')
        out.append(_label(label, x1, y1, "#ffe14d", s))
    for label, pts in gates:
        d = " ".join(f"{x:.1f},{y:.1f}" for x, y in pts)
        tag = "polyline" if len(pts) == 2 else "polygon"
        out.append(f'<{tag} points="{d}" fill="#ff8a3d" fill-opacity="0.15" stroke="#ff8a3d" '
                   f'stroke-width="{3 * s:.2f}" stroke-dasharray="{8 * s:.1f} {5 * s:.1f}"/>')
        seen = _clip(pts, width, height) if len(pts) == 2 else pts
        mx = sum(x for x, _ in seen) / len(seen)
        my = sum(y for _, y in seen) / len(seen)
        out.append(_label(label, mx, min(max(my, 0.0), height - 4 * s), "#ff8a3d", s,
                          width))
    out.append("</svg>")
    return "".join(out)


def _clip(pts: Sequence[Sequence[float]], width: float, height: float
          ) -> list[tuple[float, float]]:
    """The part of segment pts inside the image (Liang-Barsky); the segment if none is."""
    (x1, y1), (x2, y2) = pts
    dx, dy = x2 - x1, y2 - y1
    lo, hi = 0.0, 1.0
    for p, q in ((-dx, x1), (dx, width - x1), (-dy, y1), (dy, height - y1)):
        if p == 0:
            if q < 0:
                return [(x1, y1), (x2, y2)]
            continue
        r = q / p
        lo, hi = (max(lo, r), hi) if p < 0 else (lo, min(hi, r))
    if lo > hi:
        return [(x1, y1), (x2, y2)]
    return [(x1 + lo * dx, y1 + lo * dy), (x1 + hi * dx, y1 + hi * dy)]


def _label(text: str, x: float, y: float, colour: str, s: float,
           width: float | None = None) -> str:
    """A text on a dark box at (x, y); with `width`, moved left or right into the image."""
    fs = 13 * s
    w = 0.62 * fs * len(text) + 8 * s
    if width is not None:
        x = min(max(x, 0.0), width - w)
    y = max(y, fs + 6 * s)                    # keep a label at the top edge in view
    return (f'<g><rect x="{x:.1f}" y="{y - fs - 4 * s:.1f}" width="{w:.1f}" height="{fs + 6 * s:.1f}" '
            f'rx="{3 * s:.1f}" fill="#111" opacity="0.75"/><text x="{x + 4 * s:.1f}" '
            f'y="{y - 3 * s:.1f}" font-size="{fs:.1f}" fill="{colour}">{escape(text)}</text></g>')
