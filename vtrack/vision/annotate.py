"""Frame annotation for --save-frames / --save-video, and atomic JPEG output.

Confirmed tracks: solid box in the track's colour with its id; coasting tracks (no detection
this frame, drawn at the prediction): thin dashed grey box tagged "coast"; trails in the
track's colour; detections: small crosses (motion-only blobs), and for the boxes the
appearance model drew a thin box with the class and score, cyan where motion saw the
vehicle too, orange where only appearance did (a standing vehicle); counting lines with
their forward/backward counts; gates (a line or polygon) and zones (a polygon) with their
names; the frame number. Everything is plain OpenCV drawing on one copy of the frame.
"""

from __future__ import annotations

import colorsys
import functools
import os
from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from vtrack.fileio import atomic_open
from vtrack.vision.detect import Detections

FONT = cv2.FONT_HERSHEY_SIMPLEX
COAST_BGR = (170, 170, 170)
DETECTION_BGR = (0, 255, 255)
PROVENANCE_BGR = {1: (0, 140, 255), 2: (255, 255, 0)}   # appearance only, both (fusion.py)
LINE_BGR = (255, 0, 255)
REGION_BGR = (80, 220, 80)
TEXT_BGR = (255, 255, 255)


@functools.lru_cache(maxsize=4096)
def track_colour(track_id: int) -> tuple[int, int, int]:
    """A stable, saturated BGR colour per id (golden-ratio steps around the hue circle)."""
    r, g, b = colorsys.hsv_to_rgb((track_id * 0.618033988749895) % 1.0, 0.85, 1.0)
    return int(255 * b), int(255 * g), int(255 * r)


@functools.lru_cache(maxsize=64)
def _style(width: int, height: int) -> tuple[float, int]:
    """Font scale and line thickness for an image size (readable from 320x240 to 4K)."""
    scale = min(width, height) / 720.0
    return max(0.35, 0.5 * scale), max(1, round(2 * scale))


def _label(img: np.ndarray, text: str, x: int, y: int, colour: tuple[int, int, int],
           font: float, thick: int) -> None:
    """Text on a filled box whose bottom-left corner is (x, y), kept inside the image."""
    (tw, th), base = cv2.getTextSize(text, FONT, font, thick)
    x = min(max(x, 0), max(img.shape[1] - tw - 2, 0))
    y = min(max(y, th + base + 2), img.shape[0])
    cv2.rectangle(img, (x, y - th - base - 2), (x + tw + 2, y), colour, cv2.FILLED)
    cv2.putText(img, text, (x + 1, y - base), FONT, font, (0, 0, 0), thick, cv2.LINE_AA)


def _dashed_rect(img: np.ndarray, x0: int, y0: int, x1: int, y1: int,
                 colour: tuple[int, int, int], dash: int = 6) -> None:
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
    for (ax, ay), (bx, by) in zip(corners, corners[1:]):
        length = max(abs(bx - ax), abs(by - ay))
        for s in range(0, length, 2 * dash):
            e = min(s + dash, length)
            t0, t1 = s / max(length, 1), e / max(length, 1)
            cv2.line(img, (round(ax + (bx - ax) * t0), round(ay + (by - ay) * t0)),
                     (round(ax + (bx - ax) * t1), round(ay + (by - ay) * t1)), colour, 1)


def draw_frame(image: np.ndarray, *, ids: Sequence[int], boxes: np.ndarray | Sequence,
               coasted: Sequence[bool],
               trails: Mapping[int, Sequence[tuple[float, float]]],
               detections: Detections | None,
               lines: Sequence[tuple[float, float, float, float]],
               counts: Sequence[tuple[int, int]], frame_index: int,
               regions: Sequence[tuple[str, np.ndarray]] = ()) -> np.ndarray:
    """Annotated copy of `image` (HxWx3 BGR); `image` itself is not modified.

    ids/boxes/coasted: one entry per track shown (boxes x, y, w, h in pixels); trails: past
    box centres per id; lines and counts: one (x1, y1, x2, y2) and (forward, backward) each;
    regions: named gates and zones, (name, points (n, 2) in pixels): two points a line,
    more a polygon.
    """
    out = image.copy()
    font, thick = _style(out.shape[1], out.shape[0])
    for name, points in regions:
        _draw_region(out, name, np.asarray(points, dtype=np.float64).reshape(-1, 2), font,
                     thick)
    for tid, pts in trails.items():
        if len(pts) > 1:
            poly = np.round(np.asarray(pts, dtype=np.float64)).astype(np.int32)
            cv2.polylines(out, [poly], False, track_colour(int(tid)), thick, cv2.LINE_AA)
    if detections is not None:
        for cx, cy in np.round(detections.centers).astype(int):
            cv2.drawMarker(out, (int(cx), int(cy)), DETECTION_BGR, cv2.MARKER_CROSS,
                           6 + 2 * thick, 1)
        _draw_looks(out, detections, font)
    for tid, box, coast in zip(ids, np.asarray(boxes, dtype=np.float64).reshape(-1, 4),
                               coasted):
        x0, y0 = round(box[0]), round(box[1])
        x1, y1 = round(box[0] + box[2]), round(box[1] + box[3])
        if coast:
            _dashed_rect(out, x0, y0, x1, y1, COAST_BGR)
            _label(out, f"{tid} coast", x0, y0, COAST_BGR, font, 1)
        else:
            colour = track_colour(int(tid))
            cv2.rectangle(out, (x0, y0), (x1, y1), colour, thick)
            _label(out, str(tid), x0, y0, colour, font, 1)
    for (x1, y1, x2, y2), (fwd, bwd) in zip(lines, counts):
        p, q = (round(x1), round(y1)), (round(x2), round(y2))
        cv2.line(out, p, q, LINE_BGR, thick, cv2.LINE_AA)
        _label(out, f"fwd {fwd}  bwd {bwd}", (p[0] + q[0]) // 2, (p[1] + q[1]) // 2 - 2,
               LINE_BGR, font, 1)
    _label(out, f"frame {frame_index}", 0, 0, TEXT_BGR, font, 1)
    return out


def _draw_region(out: np.ndarray, name: str, points: np.ndarray, font: float, thick: int
                 ) -> None:
    """A gate or zone: its line or closed polygon, named at its middle."""
    poly = np.round(points).astype(np.int32)
    cv2.polylines(out, [poly], len(poly) > 2, REGION_BGR, thick, cv2.LINE_AA)
    x, y = np.round(points.mean(axis=0)).astype(int)
    _label(out, name, int(x), int(y), REGION_BGR, font, 1)


def _draw_looks(out: np.ndarray, dets: Detections, font: float) -> None:
    """The appearance model's boxes: thin, coloured by provenance, with class and score."""
    from vtrack.vision.appearance import VEHICLE_CLASSES

    for box, src, cls, score in zip(dets.boxes, dets.source, dets.cls, dets.score):
        if src == 0:
            continue
        x0, y0 = round(box[0]), round(box[1])
        x1, y1 = round(box[0] + box[2]), round(box[1] + box[3])
        colour = PROVENANCE_BGR[int(src)]
        cv2.rectangle(out, (x0, y0), (x1, y1), colour, 1)
        name = VEHICLE_CLASSES[cls] if cls >= 0 else "?"
        cv2.putText(out, f"{name} {score:.2f}", (x0, min(y1 + 10, out.shape[0] - 2)), FONT,
                    0.6 * font, colour, 1, cv2.LINE_AA)


def save_jpeg(path: str | os.PathLike, image: np.ndarray, quality: int = 90) -> None:
    """Encode `image` as JPEG and write it atomically (no half-written file on interrupt)."""
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError(f"{path}: JPEG encoding failed")
    with atomic_open(path, "wb", durable=False) as fh:
        fh.write(data.tobytes())
