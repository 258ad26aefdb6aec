"""`vtrack track`: video -> MOG2 detections -> tracker -> tracks.csv, summary.json, the
traffic analytics (vtrack.analytics.traffic: crossings, vehicles, counts, zone events),
annotated frames/video and an optional rerun recording.

Outputs are written atomically; on an interruption or a decoder failure the frames processed
so far are flushed to valid files with "complete": false in summary.json.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vtrack import __version__
from vtrack.analytics.calibration import Calibration
from vtrack.analytics.traffic import TrafficAnalytics
from vtrack.app.config import AppConfig
from vtrack.fileio import replace_dir, write_csv, write_json
from vtrack.tracking.tracker import FrameTracks, Tracker


@dataclass
class TrackOptions:
    save_frames: bool = False
    save_video: bool = False
    rerun: str | None = None          # path of the .rrd to write
    rerun_spawn: bool = False         # also stream to a live viewer
    max_frames: int | None = None
    progress: bool = False
    calibration: Calibration | None = None   # ground plane: speeds, lengths, classes
    bin_seconds: float = 60.0                 # time bin of counts.csv


@dataclass
class _Outputs:
    """Everything accumulated during a run, flushed by `write`."""

    rows: list[np.ndarray] = field(default_factory=list)   # (R, 7) blocks of ROW_COLUMNS


def _center(box: list[float]) -> np.ndarray:
    return np.array([box[0] + box[2] / 2.0, box[1] + box[3] / 2.0])


class TrackJob:
    """One video tracked into one output folder."""

    def __init__(self, video: str | Path, out_dir: str | Path, cfg: AppConfig,
                 opts: TrackOptions) -> None:
        self.video = Path(video)
        self.out = Path(out_dir)
        self.cfg = cfg
        self.opts = opts
        self.acc = _Outputs()
        self.analytics: TrafficAnalytics | None = None
        self.trails: dict[int, list[tuple[float, float]]] = {}
        self.info: Any = None
        self.frames = 0
        self.elapsed = 0.0

    # ------------------------------------------------------------------ running
    def run(self) -> dict[str, Any]:
        """Track the whole video; returns the summary (also on interruption, then re-raised)."""
        from vtrack.vision.detect import MotionDetector
        from vtrack.vision.video import VideoReader

        reader = VideoReader(self.video, max_frames=self.opts.max_frames)
        self.info = reader.info
        try:
            self.analytics = TrafficAnalytics(
                self.out, self.info.width, self.info.height, self.info.fps,
                self.cfg.count_lines, self.cfg.zones, self.opts.calibration,
                self.opts.bin_seconds)
        except BaseException:
            reader.close()
            raise
        self._prepare_out_dir()
        self.analytics.flush()
        complete = False
        writer = logger = bar = None
        try:
            detector = MotionDetector(self.cfg.detector, self.info.width, self.info.height)
            tracker = Tracker(self.cfg.tracker, self.info.width, self.info.height)
            writer = self._open_writer()
            logger = self._open_rerun()
            bar = self._progress()
            t0 = time.perf_counter()
            for frame in reader:
                dets = detector.detect(frame.image)
                ft = tracker.step(frame.index, frame.time, dets.centers, dets.boxes)
                self.frames = frame.index
                self._record(ft)
                self.analytics.add_frame(frame.index, frame.time, ft)
                if self.opts.save_frames or writer is not None:
                    self._annotate(frame, ft, dets, writer)
                if logger is not None:
                    logger.log_frame(frame, dets, ft, detector.foreground)
                    logger.log_trails(self.trails)
                self.elapsed = time.perf_counter() - t0
                if bar is not None:
                    bar.update(1)
            complete = True
        finally:
            reader.close()
            if bar is not None:
                bar.close()
            if writer is not None:
                writer.close()
            if logger is not None:
                logger.close()
            summary = self._write(complete)
        return summary

    def _prepare_out_dir(self) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        # Re-running into a folder replaces it: no stale frames or video from an earlier run.
        for stale in ("annotated.mp4",):
            (self.out / stale).unlink(missing_ok=True)
        if (self.out / "frames").exists() or self.opts.save_frames:
            replace_dir(self.out / "frames")
            if not self.opts.save_frames:
                (self.out / "frames").rmdir()

    def _open_writer(self) -> Any:
        if not self.opts.save_video:
            return None
        from vtrack.vision.video import VideoWriterAtomic

        return VideoWriterAtomic(self.out / "annotated.mp4", self.info.fps,
                                 (self.info.width, self.info.height))

    def _open_rerun(self) -> Any:
        if not (self.opts.rerun or self.opts.rerun_spawn):
            return None
        from vtrack.viz.rerun_log import TrackLogger  # imports rerun only when asked

        return TrackLogger(self.opts.rerun, self.info, self.cfg, spawn=self.opts.rerun_spawn)

    def _progress(self) -> Any:
        if not self.opts.progress:
            return None
        from tqdm import tqdm

        total = self.info.frame_count or None
        if self.opts.max_frames:
            total = min(total or self.opts.max_frames, self.opts.max_frames)
        return tqdm(total=total, unit="frame", desc=self.video.name, file=sys.stderr,
                    dynamic_ncols=True)

    # ---------------------------------------------------------------- recording
    def _record(self, ft: FrameTracks) -> None:
        self.acc.rows.append(ft.rows)
        for _, tid, *box, _ in ft.rows:
            c = _center(box)
            trail = self.trails.setdefault(int(tid), [])
            trail.append((float(c[0]), float(c[1])))
            del trail[: -self.cfg.output.trail_length]

    def _annotate(self, frame: Any, ft: FrameTracks, dets: Any, writer: Any) -> None:
        from vtrack.vision.annotate import draw_frame, save_jpeg

        img = draw_frame(frame.image, ids=ft.ids, boxes=ft.boxes, coasted=ft.coasted,
                         trails={i: self.trails.get(int(i), []) for i in ft.ids},
                         detections=dets, lines=self.analytics.lines_px,
                         counts=self.analytics.line_counts(),
                         frame_index=frame.index)
        if self.opts.save_frames:
            save_jpeg(self.out / "frames" / f"{frame.index:06d}.jpg", img,
                      quality=self.cfg.output.jpeg_quality)
        if writer is not None:
            writer.write(img)

    # ------------------------------------------------------------------ writing
    def _write(self, complete: bool) -> dict[str, Any]:
        rows = np.concatenate(self.acc.rows) if self.acc.rows else np.zeros((0, 7))
        rows = rows[np.lexsort((rows[:, 1], rows[:, 0]))]
        write_csv(self.out / "tracks.csv", (
            [int(r[0]), int(r[1]), *(f"{v:.2f}" for v in r[2:6]), f"{r[6]:.3f}", -1, -1, -1]
            for r in rows))
        summary = {
            "video": str(self.video),
            "frames": self.frames,
            "width": self.info.width,
            "height": self.info.height,
            "fps_video": float(self.info.fps),
            "fps_processed": round(self.frames / self.elapsed, 2) if self.elapsed > 0 else 0.0,
            "tracks": int(len(np.unique(rows[:, 1]))),
            "complete": complete,
            **self.analytics.flush(final=True),   # counts, zones, calibration
            "vtrack_version": __version__,
            "config_hash": self.cfg.digest(),
            "config": self.cfg.to_dict(),
        }
        write_json(self.out / "summary.json", summary)
        return summary


def track_video(video: str | Path, out_dir: str | Path, cfg: AppConfig,
                opts: TrackOptions | None = None) -> dict[str, Any]:
    """Track one video into `out_dir`; returns summary.json's content."""
    return TrackJob(video, out_dir, cfg, opts or TrackOptions()).run()
