"""MOT metrics (MOTA, IDF1, HOTA) on MOTChallenge CSV files, computed by trackeval 1.3.0.

Files have no header, one row per box: `frame,id,bb_left,bb_top,bb_width,bb_height,conf,x,y,z`
and optionally an 11th column, the visible fraction. Ground-truth rows whose visible fraction
is under 0.3 (or whose conf is 0, MOTChallenge's "ignore" mark) are ignore regions: a tracker
box matched to one is neither a hit nor a false positive.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from vtrack.boxes import iou as box_iou
from vtrack.errors import InputError
from vtrack.fileio import open_input

MIN_VISIBILITY = 0.3
MATCH_IOU = 0.5
INSTALL_HINT = "pip install --no-deps trackeval==1.3.0 tabulate"
_TRACKER = "vtrack"


# ----------------------------------------------------------------------------- reading

def read_mot(path: str | os.PathLike, min_cols: int = 10, max_cols: int = 11) -> np.ndarray:
    """Read a MOTChallenge CSV into a float array of shape (rows, cols).

    Every row must have the same number of columns, between `min_cols` and `max_cols`;
    frame is an integer >= 1, id an integer >= 1, width and height positive, no value
    non-finite, and no (frame, id) pair twice. A file without rows gives a (0, min_cols)
    array. Anything else raises InputError naming the file and the line.
    """
    path = Path(path)
    lines = _read_lines(path)
    rows: list[list[float]] = []
    line_nos: list[int] = []
    for line_no, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        rows.append(_parse_row(path, line_no, line, min_cols, max_cols))
        if len(rows[-1]) != len(rows[0]):
            raise InputError(f"{path}: line {line_no}: {len(rows[-1])} columns, "
                             f"but line {line_nos[0]} has {len(rows[0])}")
        line_nos.append(line_no)
    if not rows:
        return np.zeros((0, min_cols))
    data = np.array(rows, dtype=float)
    _check_values(path, data, np.array(line_nos))
    return data


def _read_lines(path: Path) -> list[str]:
    try:
        with open_input(path, "CSV file", encoding="utf-8") as fh:
            return fh.read().splitlines()
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None


def _parse_row(path: Path, line_no: int, line: str, min_cols: int, max_cols: int) -> list[float]:
    cells = [c.strip() for c in line.split(",")]
    if not min_cols <= len(cells) <= max_cols:
        want = f"{min_cols}" if min_cols == max_cols else f"{min_cols} to {max_cols}"
        raise InputError(f"{path}: line {line_no}: {len(cells)} columns, expected {want}")
    values = []
    for col, cell in enumerate(cells, start=1):
        try:
            value = float(cell)
        except ValueError:
            raise InputError(f"{path}: line {line_no}: column {col} is not a number: "
                             f"{cell[:20]!r}") from None
        if not math.isfinite(value):
            raise InputError(f"{path}: line {line_no}: column {col} is not finite: {cell!r}")
        values.append(value)
    return values


def _check_values(path: Path, data: np.ndarray, line_nos: np.ndarray) -> None:
    checks = [
        ((data[:, 0] < 1) | (data[:, 0] != np.round(data[:, 0])), "frame must be an integer >= 1"),
        ((data[:, 1] < 1) | (data[:, 1] != np.round(data[:, 1])), "id must be an integer >= 1"),
        ((data[:, 4] <= 0) | (data[:, 5] <= 0), "box width and height must be positive"),
    ]
    for bad, what in checks:
        if bad.any():
            raise InputError(f"{path}: line {line_nos[np.argmax(bad)]}: {what}")
    keys = data[:, 0].astype(np.int64) * (1 << 32) + data[:, 1].astype(np.int64)
    _, first, counts = np.unique(keys, return_index=True, return_counts=True)
    if (counts > 1).any():
        dup = keys == keys[first[np.argmax(counts > 1)]]
        a, b = line_nos[dup][:2]
        raise InputError(f"{path}: line {b}: frame {int(data[dup][0, 0])} repeats id "
                         f"{int(data[dup][0, 1])} of line {a}")


# ----------------------------------------------------------------------------- ignore rule

def ignore_mask(gt: np.ndarray) -> np.ndarray:
    """Boolean mask of ground-truth rows that are ignore regions (visible < 0.3 or conf 0)."""
    mask = gt[:, 6] == 0
    if gt.shape[1] >= 11:
        mask |= gt[:, 10] < MIN_VISIBILITY
    return mask


def match_boxes(a: np.ndarray, b: np.ndarray, min_iou: float = MATCH_IOU
                ) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one pairs (rows into a, cols into b) of boxes a (n, 4) and b (m, 4) with
    IoU >= min_iou: the Hungarian method on IoU, the threshold less a float eps (trackeval's
    MATCH_IOU by default)."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    iou = box_iou(a, b)
    iou[iou < min_iou - np.finfo(float).eps] = 0.0
    rows, cols = linear_sum_assignment(-iou)
    matched = iou[rows, cols] > 0
    return rows[matched], cols[matched]


def detected(truth: np.ndarray, dets: np.ndarray, min_iou: float = MATCH_IOU) -> np.ndarray:
    """(n,) whether each box of `truth` (n, 4) has a box of `dets` (m, 4), one to one at
    IoU >= min_iou (`match_boxes`): a detector's recall and precision
    (scripts/eval_realboxes.py, eval_far.py), a false positive's cause (false_positives)."""
    found = np.zeros(len(truth), dtype=bool)
    found[match_boxes(truth, dets, min_iou)[0]] = True
    return found


def drop_ignored(gt: np.ndarray, tracks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Remove ignore GT rows, and the tracker rows matched to them (MOTChallenge preprocessing).

    Per frame, tracker boxes are matched to ALL ground-truth boxes by the Hungarian method on
    IoU >= 0.5; a tracker box whose match is an ignore box is dropped.
    """
    ignore = ignore_mask(gt)
    keep = np.ones(len(tracks), dtype=bool)
    for frame in np.unique(gt[ignore, 0]):
        g = gt[:, 0] == frame
        t = np.flatnonzero(tracks[:, 0] == frame)
        rows, cols = match_boxes(gt[g, 2:6], tracks[t, 2:6])
        keep[t[cols[ignore[g][rows]]]] = False
    return gt[~ignore], tracks[keep]


# ----------------------------------------------------------------------------- scoring

def evaluate(gt_path: str | os.PathLike, tracks_path: str | os.PathLike) -> dict[str, Any]:
    """Score a tracks file against a ground-truth file; see `evaluate_arrays` for the keys."""
    gt = read_mot(gt_path)
    if len(gt) == 0:
        raise InputError(f"{gt_path}: no ground-truth rows")
    return evaluate_arrays(gt, read_mot(tracks_path))


def evaluate_arrays(gt: np.ndarray, tracks: np.ndarray) -> dict[str, Any]:
    """Score tracker rows against ground-truth rows (arrays as returned by `read_mot`).

    Returns mota, idf1, hota (fractions; hota is the mean over IoU thresholds 0.05..0.95),
    id_switches, false_positives, misses, and detail keys (true_positives, precision, recall,
    deta, assa, motp, gt_ids, pred_ids, gt_boxes, pred_boxes, ignored_gt_boxes,
    ignored_pred_boxes, frames).
    """
    frames = _frames(gt, tracks)
    gt_kept, tracks_kept = drop_ignored(gt, tracks)
    raw = _run_trackeval([(gt_kept, tracks_kept, max(frames, 1))])[_seq(0)]
    return _scores(raw) | {
        "gt_ids": len(np.unique(gt_kept[:, 1])),
        "pred_ids": len(np.unique(tracks_kept[:, 1])),
        "gt_boxes": len(gt_kept),
        "pred_boxes": len(tracks_kept),
        "ignored_gt_boxes": len(gt) - len(gt_kept),
        "ignored_pred_boxes": len(tracks) - len(tracks_kept),
        "frames": frames,
    }


def evaluate_combined(sequences: list[tuple[np.ndarray, np.ndarray]]) -> dict[str, Any]:
    """MOTChallenge's combined scores over several sequences, each a (gt, tracks) pair of
    arrays: trackeval pools the sequences' counts (CLEAR's TP / FP / FN / IDSW and
    Identity's IDTP / IDFP / IDFN summed; HOTA from the summed per-threshold counts), the
    way its leaderboards rank trackers, so a sequence weighs by its boxes (a mean of
    per-sequence scores weighs each sequence alike). Keys as `evaluate_arrays`' scores
    (mota ... motp), with gt_boxes and pred_boxes summed."""
    if not sequences:
        raise ValueError("evaluate_combined needs at least one sequence")
    kept = [(*drop_ignored(gt, tracks), max(_frames(gt, tracks), 1))
            for gt, tracks in sequences]
    raw = _run_trackeval(kept)["COMBINED_SEQ"]
    return _scores(raw) | {"gt_boxes": sum(len(g) for g, _, _ in kept),
                           "pred_boxes": sum(len(t) for _, t, _ in kept)}


def _scores(raw: dict[str, Any]) -> dict[str, Any]:
    """The headline numbers of one trackeval result (one sequence or combined)."""
    hota, clear, ident = raw["HOTA"], raw["CLEAR"], raw["Identity"]
    return {
        "mota": float(clear["MOTA"]),
        "idf1": float(ident["IDF1"]),
        "hota": float(np.mean(hota["HOTA"])),
        "id_switches": int(clear["IDSW"]),
        "false_positives": int(clear["CLR_FP"]),
        "misses": int(clear["CLR_FN"]),
        "true_positives": int(clear["CLR_TP"]),
        "precision": float(clear["CLR_Pr"]),
        "recall": float(clear["CLR_Re"]),
        "deta": float(np.mean(hota["DetA"])),
        "assa": float(np.mean(hota["AssA"])),
        "motp": float(clear["MOTP"]),
    }


def detection_scores(gt: np.ndarray, detections: np.ndarray) -> dict[str, float]:
    """Recall and precision of per-frame detections (rows of MOT columns; their ids are
    ignored) against ground truth, matched as tracks are (IoU >= 0.5, ignore regions): the
    share of the ground truth that a tracker fed with these detections covers without
    coasting, i.e. the detector's ceiling on the tracker's MOTA."""
    rows = np.array(detections, dtype=float)
    rows[:, 1] = np.arange(1, len(rows) + 1)   # each detection its own identity
    res = evaluate_arrays(gt, rows)
    return {"recall": res["recall"], "precision": res["precision"]}


def _frames(gt: np.ndarray, tracks: np.ndarray) -> int:
    """The last frame either array has a row in (0 if neither has rows)."""
    return int(max(gt[:, 0].max(initial=0), tracks[:, 0].max(initial=0)))


def _seq(i: int) -> str:
    return f"seq{i:04d}"


def _run_trackeval(sequences: list[tuple[np.ndarray, np.ndarray, int]]) -> dict[str, Any]:
    """Evaluate (gt, tracks, frames) sequences with trackeval's MotChallenge2DBox, silencing
    all its output; returns its result per sequence name (`_seq(i)`) and "COMBINED_SEQ"."""
    sink = io.StringIO()
    with (tempfile.TemporaryDirectory(prefix="vtrack-eval-") as root,
          contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink),
          warnings.catch_warnings()):
        warnings.simplefilter("ignore")
        trackeval = _import_trackeval()
        gt_root, trk_root = Path(root) / "gt", Path(root) / "trackers"
        for i, (gt, tracks, _) in enumerate(sequences):
            _write_layout(gt_root, trk_root, _seq(i), gt, tracks)
        dataset = trackeval.datasets.MotChallenge2DBox({
            "GT_FOLDER": str(gt_root), "TRACKERS_FOLDER": str(trk_root),
            "TRACKERS_TO_EVAL": [_TRACKER], "SKIP_SPLIT_FOL": True, "DO_PREPROC": False,
            "PRINT_CONFIG": False, "OUTPUT_FOLDER": None,
            "SEQ_INFO": {_seq(i): frames for i, (_, _, frames) in enumerate(sequences)}})
        evaluator = trackeval.Evaluator({
            "USE_PARALLEL": False, "BREAK_ON_ERROR": True, "LOG_ON_ERROR": None,
            "PRINT_RESULTS": False, "PRINT_CONFIG": False, "TIME_PROGRESS": False,
            "OUTPUT_SUMMARY": False, "OUTPUT_DETAILED": False, "PLOT_CURVES": False})
        metrics = [trackeval.metrics.HOTA(), trackeval.metrics.CLEAR(),
                   trackeval.metrics.Identity()]
        res, _ = evaluator.evaluate([dataset], metrics)
    by_seq = res["MotChallenge2DBox"][_TRACKER]
    return {name: r["pedestrian"] for name, r in by_seq.items()}


def _import_trackeval() -> Any:
    try:
        import trackeval
    except ImportError:
        raise InputError(f"trackeval is not installed: run `{INSTALL_HINT}`") from None
    return trackeval


def _write_layout(gt_root: Path, trk_root: Path, seq: str, gt: np.ndarray,
                  tracks: np.ndarray) -> None:
    """Write <gt_root>/<seq>/gt/gt.txt and <trk_root>/<name>/data/<seq>.txt as trackeval
    expects."""
    gt_file = gt_root / seq / "gt" / "gt.txt"
    trk_file = trk_root / _TRACKER / "data" / f"{seq}.txt"
    gt_file.parent.mkdir(parents=True)
    trk_file.parent.mkdir(parents=True, exist_ok=True)
    ones = np.ones((len(gt), 1))
    # gt: frame,id,box,conf=1,class=1,visibility=1; tracker: frame,id,box,conf,-1,-1,-1
    _savetxt(gt_file, np.hstack([gt[:, :6], ones, ones, ones]))
    _savetxt(trk_file, np.hstack([tracks[:, :7], -np.ones((len(tracks), 3))]))


def _savetxt(path: Path, rows: np.ndarray) -> None:
    np.savetxt(path, rows, fmt="%.10g", delimiter=",")
