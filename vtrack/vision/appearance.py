"""The appearance detector: a YOLOX-format ONNX model (COCO classes) that finds road users
by how they look, standing or moving (Ge et al. 2021, "YOLOX: Exceeding YOLO Series in
2021", arXiv 2107.08430).

One pass (`AppearanceModel.detect`) on the whole frame, or on one window of it (a tile,
`tiles`: the same model sees the vehicles of the window magnified):
1. letterbox: resize keeping the aspect ratio to the model's input side S (read from the
   model), pad with grey 114 at the right and bottom (YOLOX's own preprocessing: BGR,
   0-255, no mean or std) up to the next multiple of 32 where the model runs on
   rectangles (onnxsize.py frees its declared size), else to the S x S square;
2. inference: onnxruntime when installed (twice as fast as OpenCV's DNN module on these
   2 cores: docs/DETECTOR.md), else OpenCV DNN;
3. decode (YOLOX's head, anchor-free): at grid cell (i, j) of stride s in {8, 16, 32}, the
   box centre is ((dx + i) s, (dy + j) s) and its size (exp(lw) s, exp(lh) s); score =
   objectness x class probability;
4. per-class non-maximum suppression, then across classes (one box a road user);
5. riders: a person box that overlaps a motorcycle's or bicycle's is that road user's rider
   and widens its box; every other person box is dropped (a pedestrian is not a vehicle).

Boxes come back in the frame's pixels with a score and a class index into VEHICLE_CLASSES;
a window's boxes cut by its edges inside the frame are dropped (the tiles overlap: the
vehicle is whole in a neighbour, or in the whole-frame pass).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from vtrack.boxes import enclosing, intersection, iou
from vtrack.errors import InputError
from vtrack.vision.onnxsize import free_input_size

# COCO class index -> vtrack class; the person (0) is read only as a rider
COCO_VEHICLES = {1: "bicycle", 2: "car", 3: "motorcycle", 5: "bus", 7: "truck"}
VEHICLE_CLASSES = ("motorcycle", "bicycle", "car", "bus", "truck")
TWO_WHEELERS = (VEHICLE_CLASSES.index("bicycle"), VEHICLE_CLASSES.index("motorcycle"))
COCO_CLASSES = 80
PERSON = 0
STRIDES = (8, 16, 32)
PAD_GREY = 114
TILE_ZOOM = 1.75     # tiles magnify the whole-frame pass at least this much
TILE_OVERLAP = 0.15  # tiles overlap by this share of their size (a far vehicle is whole in one)
CUT_MODEL_PX = 3.0   # a window's box within this many model pixels of an inner edge is cut

SHIPPED = "yolox_nano.onnx"
SHIPPED_SHA256 = "695e750a5d5754bb5a8d5325643b59282191a7e7a564e435a415fd3c578eab14"


@dataclass
class AppearanceBoxes:
    """Road users found by appearance in one frame: boxes (K, 4) x, y, w, h in the frame's
    pixels, scores (K,) in 0..1, classes (K,) indices into VEHICLE_CLASSES; `scale`: the
    model's input pixels per frame pixel of the pass (the letterbox's r); `window`: the
    part of the frame the pass looked at."""

    boxes: np.ndarray
    scores: np.ndarray
    classes: np.ndarray
    scale: float = 1.0
    window: tuple[int, int, int, int] | None = None   # the pass's window; None: whole frame
    whole: float = 1.0   # the scale of a pass over the whole frame (= scale without a window)

    def __len__(self) -> int:
        return len(self.scores)

    def take(self, keep: np.ndarray) -> AppearanceBoxes:
        """The boxes where `keep` (K,) holds."""
        return AppearanceBoxes(self.boxes[keep], self.scores[keep], self.classes[keep],
                               self.scale, self.window, self.whole)


Window = tuple[int, int, int, int]   # x, y, w, h in a frame's pixels


def tiles(width: int, height: int, side: int) -> list[Window]:
    """The fewest windows of a grid over a width x height frame, overlapping by
    TILE_OVERLAP, in which a side x side model sees the vehicles at least TILE_ZOOM times
    as large as in the whole frame (the far, small vehicles it misses there), in reading
    order (top row first: the far band of a view down a road)."""
    whole = min(side / width, side / height)
    for n in range(2, 17):
        best = None
        for cols in range(1, n + 1):
            if n % cols:
                continue
            rows = n // cols
            tw = min(width, math.ceil(width / (cols - (cols - 1) * TILE_OVERLAP)))
            th = min(height, math.ceil(height / (rows - (rows - 1) * TILE_OVERLAP)))
            zoom = min(side / tw, side / th) / whole
            if zoom >= TILE_ZOOM and (best is None or zoom > best[0]):
                best = (zoom, cols, rows, tw, th)
        if best is not None:
            _, cols, rows, tw, th = best
            xs = np.linspace(0, width - tw, cols).round().astype(int)
            ys = np.linspace(0, height - th, rows).round().astype(int)
            return [(int(x), int(y), tw, th) for y in ys for x in xs]
    return []


def cut(boxes: np.ndarray, window: Window, width: int, height: int, margin: float
        ) -> np.ndarray:
    """(K,) whether each box (K, 4), in frame pixels, reaches within `margin` of an edge of
    `window` that is not the frame's own edge (the window cut its vehicle)."""
    x, y, w, h = window
    left = (x > 0) & (boxes[:, 0] <= x + margin)
    top = (y > 0) & (boxes[:, 1] <= y + margin)
    right = (x + w < width) & (boxes[:, 0] + boxes[:, 2] >= x + w - margin)
    bottom = (y + h < height) & (boxes[:, 1] + boxes[:, 3] >= y + h - margin)
    return left | top | right | bottom


def shipped_model() -> Path:
    """The path of the YOLOX-Nano model inside the package (vtrack/models)."""
    return Path(str(resources.files("vtrack.models").joinpath(SHIPPED)))


def letterbox(image: np.ndarray, side: int, stride: int = 0) -> tuple[np.ndarray, float]:
    """`image` resized into a side x side square keeping its aspect ratio, padded with grey
    at the right and bottom, as a (1, 3, H, W) float32 blob; and the scale r (model pixels
    per image pixel). `stride` 0: H = W = side; else each side is padded only up to a
    multiple of `stride` (YOLOv5's minimal-padding letterbox: a 16:9 frame at 416 is a
    416x256 blob, 0.62 of the square's pixels and work, for a model whose input size is free)."""
    h, w = image.shape[:2]
    r = min(side / h, side / w)
    nw, nh = max(1, round(w * r)), max(1, round(h * r))
    bh, bw = (side, side) if not stride else (-(-nh // stride) * stride, -(-nw // stride) * stride)
    padded = np.full((bh, bw, 3), PAD_GREY, dtype=np.uint8)
    padded[:nh, :nw] = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_LINEAR)
    blob = np.empty((1, 3, bh, bw), dtype=np.float32)
    for channel, plane in enumerate(cv2.split(padded)):   # 4x faster than a transposed copy
        blob[0, channel] = plane
    return blob, r


def grid(height: int, width: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """YOLOX's anchor points over a height x width input (width None: square): the cell
    (i, j) (N, 2) and the stride (N,) of each output row, strides 8, 16, 32 in order,
    row-major within each."""
    width = height if width is None else width
    cells, strides = [], []
    for s in STRIDES:
        j, i = np.mgrid[0:height // s, 0:width // s]
        cells.append(np.stack([i.ravel(), j.ravel()], axis=1))
        strides.append(np.full(i.size, s))
    return np.concatenate(cells).astype(np.float32), np.concatenate(strides).astype(np.float32)


def decode(raw: np.ndarray, cells: np.ndarray, strides: np.ndarray, min_score: float
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """YOLOX's raw output rows (N, 85) -> boxes (K, 4) x, y, w, h in model pixels, scores
    and COCO classes of the rows whose best score (objectness x class) of a vehicle or a
    person reaches `min_score`."""
    wanted = np.array([PERSON, *COCO_VEHICLES])
    scores = raw[:, 4:5] * raw[:, 5 + wanted]
    best = scores.argmax(axis=1)
    score = scores[np.arange(len(scores)), best]
    keep = score >= min_score
    r, st, c = raw[keep], strides[keep, None], cells[keep]
    centre = (r[:, :2] + c) * st
    size = np.exp(np.minimum(r[:, 2:4], 10.0)) * st
    return (np.concatenate([centre - size / 2, size], axis=1).astype(float),
            score[keep].astype(float), wanted[best[keep]])


def suppress(boxes: np.ndarray, scores: np.ndarray, classes: np.ndarray, nms_iou: float,
             cross_iou: float) -> np.ndarray:
    """Indices kept by non-maximum suppression within each class at `nms_iou`, then across
    classes at `cross_iou` (a car also scored as a truck is one road user), best first."""
    keep = []
    for c in np.unique(classes):
        idx = np.flatnonzero(classes == c)
        kept = cv2.dnn.NMSBoxes(boxes[idx].tolist(), scores[idx].tolist(), 0.0, nms_iou)
        keep.extend(idx[np.asarray(kept, dtype=int).ravel()])
    keep = np.array(sorted(keep, key=lambda i: -scores[i]), dtype=int)
    out: list[int] = []
    for i in keep:
        if not out or iou(boxes[i][None], boxes[out])[0].max() < cross_iou:
            out.append(int(i))
    return np.array(out, dtype=int)


def with_riders(boxes: np.ndarray, scores: np.ndarray, coco: np.ndarray
                ) -> AppearanceBoxes:
    """Vehicles only: each person box is given to the two-wheeler whose box covers the
    largest share of it (at least a fifth; the rider sits on it) and widens that box to
    their union; persons on no two-wheeler are dropped (pedestrians)."""
    person = coco == PERSON
    vehicle = np.flatnonzero(~person)
    classes = np.array([VEHICLE_CLASSES.index(COCO_VEHICLES[int(c)]) for c in coco[vehicle]],
                       dtype=int)
    out = boxes[vehicle].copy()
    two = np.flatnonzero(np.isin(classes, TWO_WHEELERS))
    for p in np.flatnonzero(person):
        if not len(two):
            break
        share = intersection(out[two], boxes[p]) / max(boxes[p, 2] * boxes[p, 3], 1e-9)
        k = int(share.argmax())
        if share[k] >= 0.2:
            out[two[k]] = enclosing(np.stack([out[two[k]], boxes[p]]))
    return AppearanceBoxes(out, scores[vehicle], classes)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


class _Runner:
    """One inference engine over the model: onnxruntime when installed, else OpenCV DNN.
    `input_side` is read from the model; calling it on a blob returns the raw rows (N, C).
    For onnxruntime the model's input height and width are made free (onnxsize.py), as
    they are in OpenCV DNN, so a blob may be smaller than side x side."""

    def __init__(self, path: Path, threads: int, engine: str) -> None:
        self.engine = engine
        if engine == "onnxruntime":
            import onnxruntime as ort

            model, shape = free_input_size(path.read_bytes())
            if len(shape) != 4 or shape[1] != 3 or not shape[2] or shape[2] != shape[3]:
                raise ValueError(f"input shape {list(shape)} is not 1x3xSxS")
            self.input_side = shape[2]
            opts = ort.SessionOptions()
            opts.intra_op_num_threads = max(1, threads)
            opts.inter_op_num_threads = 1
            opts.log_severity_level = 3
            self.session = ort.InferenceSession(model, opts, providers=["CPUExecutionProvider"])
            self.input_name = self.session.get_inputs()[0].name
        else:
            self.net = cv2.dnn.readNetFromONNX(str(path))
            self.input_side = _probe_side(self.net)

    def __call__(self, blob: np.ndarray) -> np.ndarray:
        if self.engine == "onnxruntime":
            out = self.session.run(None, {self.input_name: blob})[0]
        else:
            self.net.setInput(blob)
            out = self.net.forward()
        return np.asarray(out)[0]


def _probe_side(net: Any) -> int:
    """OpenCV DNN keeps no input shape: the side whose YOLOX grid the output matches."""
    for side in (416, 640, 320, 512, 608, 224, 256, 288, 384, 448, 480, 544, 576, 672, 736,
                 800, 960, 1024, 1280):
        net.setInput(np.zeros((1, 3, side, side), np.float32))
        try:
            out = net.forward()
        except cv2.error:
            continue
        if out.ndim == 3 and out.shape[1] == len(grid(side)[1]):
            return side
    raise ValueError("no input size whose YOLOX grid matches the output")


def default_engine() -> str:
    """"onnxruntime" when it is installed, else "opencv"."""
    try:
        import onnxruntime  # noqa: F401
    except ImportError:
        return "opencv"
    return "onnxruntime"


class AppearanceModel:
    """A YOLOX-format ONNX model (COCO's 80 classes) read once; `detect` runs one pass.
    Where the model runs on a rectangular input (YOLOX does), a pass letterboxes only to
    the next multiple of 32 (`stride`), not to the whole square.

    `path` None: the shipped YOLOX-Nano, whose SHA-256 is checked at load. A missing,
    corrupt or non-YOLOX file raises InputError naming it."""

    def __init__(self, path: str | Path | None = None, min_score: float = 0.3,
                 nms_iou: float = 0.45, cross_iou: float = 0.7, threads: int = 1,
                 engine: str | None = None) -> None:
        shipped = path is None or str(path) == ""
        self.path = shipped_model() if shipped else Path(path)
        if not self.path.is_file():
            raise InputError(f"{self.path}: appearance model not found")
        if shipped and _sha256(self.path) != SHIPPED_SHA256:
            raise InputError(f"{self.path}: the shipped model's checksum does not match "
                             f"(reinstall vtrack)")
        self.engine = engine or default_engine()
        try:
            self.run = _Runner(self.path, threads, self.engine)
            side = self.run.input_side
            self._grids = {(side, side): grid(side)}
            probe = self.run(np.full((1, 3, side, side), PAD_GREY, np.float32))
        except InputError:
            raise
        except Exception as exc:   # onnxruntime's and OpenCV's own errors, any text
            first = str(exc).strip().splitlines()[0][:160] if str(exc).strip() else ""
            raise InputError(f"{self.path}: not a readable YOLOX ONNX model ({first})"
                             ) from None
        if probe.ndim != 2 or probe.shape[0] != len(self._grids[side, side][1]):
            raise InputError(f"{self.path}: output {probe.shape} is not YOLOX's rows over "
                             f"strides 8, 16, 32 of a {side} input")
        if probe.shape[1] != 5 + COCO_CLASSES:
            raise InputError(f"{self.path}: {probe.shape[1] - 5} classes, not COCO's 80: no "
                             f"vehicle classes vtrack can read")
        self.side = side
        self.stride = STRIDES[-1] if self._runs_rectangles() else 0
        self.min_score, self.nms_iou, self.cross_iou = min_score, nms_iou, cross_iou

    def _runs_rectangles(self) -> bool:
        """Whether the model runs on a side x (side / 2) input, with YOLOX's rows for it."""
        height = max(STRIDES[-1], self.side // 2 // STRIDES[-1] * STRIDES[-1])
        try:
            out = self.run(np.full((1, 3, height, self.side), PAD_GREY, np.float32))
        except Exception:   # a graph with a fixed size somewhere: square passes only
            return False
        return out.shape == (len(self._grid(height, self.side)[1]), 5 + COCO_CLASSES)

    def _grid(self, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
        """grid(height, width), computed once per input shape."""
        if (height, width) not in self._grids:
            self._grids[height, width] = grid(height, width)
        return self._grids[height, width]

    def detect(self, image: np.ndarray, window: Window | None = None) -> AppearanceBoxes:
        """The road users in the frame `image` (BGR uint8), or in its `window` (those the
        window cuts dropped), in the frame's pixels."""
        x, y = (0, 0) if window is None else window[:2]
        crop = image if window is None else image[y:y + window[3], x:x + window[2]]
        blob, r = letterbox(crop, self.side, self.stride)
        boxes, scores, coco = decode(self.run(blob), *self._grid(*blob.shape[2:]),
                                     self.min_score)
        boxes /= r
        boxes[:, :2] += (x, y)
        keep = suppress(boxes, scores, coco, self.nms_iou, self.cross_iou)
        found = with_riders(boxes[keep], scores[keep], coco[keep])
        found.scale, found.window = r, window
        found.whole = min(self.side / image.shape[0], self.side / image.shape[1])
        if window is not None:
            found = found.take(~cut(found.boxes, window, image.shape[1], image.shape[0],
                                    CUT_MODEL_PX / r))
        return found
