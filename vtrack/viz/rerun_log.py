"""The one place that imports rerun (rerun-sdk 0.41 API: set_time, Scalars, RecordingStream).

Layout of a `vtrack track` recording (timeline `frame`, plus `video_time` in seconds):
    camera/image                 video frame (JPEG, downscaled to output.rerun_image_width)
    camera/foreground            MOG2 foreground mask (with output.rerun_foreground)
    camera/detections            detection boxes; camera/detections/centroids their centres
    camera/tracks/<id>           the track's box: coloured when detected, grey while coasting
    camera/trails/<id>           recent path of the track
    camera/covariance/<id>       2-sigma position covariance ellipse (a line strip)
    tracks/<id>/{speed,acceleration,innovation}   per-track time series (px/s, px/s^2, px)
    metrics/{tracks,detections}  counts per frame
A track's box entity holds exactly its rows of tracks.csv (rows emitted at confirmation are
logged at their own frames) and is cleared on the frame after its last row.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from vtrack.errors import MissingExtraError
from vtrack.vision.annotate import track_colour

try:
    import rerun as rr
    import rerun.blueprint as rrb
except ImportError:  # pragma: no cover - exercised only without the extra
    rr = None


def _require() -> None:
    if rr is None:
        raise MissingExtraError("rerun", "rerun-sdk")


def track_color(track_id: int) -> tuple[int, int, int]:
    """The id's RGB colour: the same one the annotated frames use (vision.annotate)."""
    b, g, r = track_colour(track_id)
    return r, g, b


def ellipse_points(mean: np.ndarray, cov: np.ndarray, k: float = 2.0, n: int = 32) -> np.ndarray:
    """Points of the k-sigma ellipse of a 2x2 covariance (rerun's Ellipses2D cannot rotate)."""
    d, U = np.linalg.eigh(0.5 * (cov + cov.T))
    a = np.linspace(0, 2 * np.pi, n + 1)
    circle = np.stack([np.cos(a), np.sin(a)], axis=1)
    return mean + k * (circle * np.sqrt(np.clip(d, 0, None))) @ U.T


def _open(app: str, path: str | Path | None, blueprint: Any, spawn: bool = False) -> Any:
    _require()
    rec = rr.RecordingStream(app)
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
    if path is not None and spawn:
        rec.spawn(default_blueprint=blueprint)
        rec.set_sinks(rr.FileSink(str(path)), rr.GrpcSink())
        rec.send_blueprint(blueprint)
    elif path is not None:
        rec.save(str(path), default_blueprint=blueprint)
    else:
        rec.spawn(default_blueprint=blueprint)
    return rec


class TrackLogger:
    """Logs one `vtrack track` run frame by frame."""

    def __init__(self, path: str | Path | None, info: Any, cfg: Any, spawn: bool = False) -> None:
        bp = rrb.Blueprint(
            rrb.Horizontal(
                rrb.Spatial2DView(name="camera", origin="/camera"),
                rrb.Vertical(
                    rrb.TimeSeriesView(name="speed (px/s)", origin="/tracks",
                                       contents="/tracks/*/speed"),
                    rrb.TimeSeriesView(name="innovation (px)", origin="/tracks",
                                       contents="/tracks/*/innovation"),
                    rrb.TimeSeriesView(name="counts", origin="/metrics"),
                ),
                column_shares=[3, 2],
            ),
            collapse_panels=True,
        )
        self.rec = _open("vtrack", path, bp, spawn)
        self.cfg = cfg.output
        self.scale = max(1.0, info.width / max(1, self.cfg.rerun_image_width))
        self.live: set[int] = set()
        self.last_frame = 0
        self.fps = info.fps
        rec = self.rec
        rec.log("camera/image", rr.Transform3D(scale=[self.scale, self.scale, 1.0]), static=True)
        rec.log("metrics/tracks", rr.SeriesLines(names="confirmed tracks"), static=True)
        rec.log("metrics/detections", rr.SeriesLines(names="detections"), static=True)
        if cfg.count_lines:
            px = [l.pixels(info.width, info.height) for l in cfg.count_lines]
            rec.log("camera/count_lines",
                    rr.LineStrips2D([[l[:2], l[2:]] for l in px],
                                    labels=[f"line {l.name or k}"
                                            for k, l in enumerate(cfg.count_lines)],
                                    colors=(255, 255, 0)), static=True)

    def _time(self, frame: int, t: float | None = None) -> None:
        self.rec.set_time("frame", sequence=frame)
        if t is not None:
            self.rec.set_time("video_time", duration=t)

    def log_frame(self, frame: Any, dets: Any, ft: Any, foreground: np.ndarray | None) -> None:
        """Log one processed frame: image, detections, track boxes/trails/ellipses, series."""
        import cv2

        rec = self.rec
        self._time(frame.index, frame.time)
        img = frame.image
        if self.scale > 1:
            img = cv2.resize(img, None, fx=1 / self.scale, fy=1 / self.scale,
                             interpolation=cv2.INTER_AREA)
        rec.log("camera/image", rr.Image(img, color_model="BGR").compress(
            jpeg_quality=self.cfg.rerun_jpeg_quality))
        if self.cfg.rerun_foreground and foreground is not None:
            rec.log("foreground", rr.Image(foreground).compress(jpeg_quality=80))
        rec.log("camera/detections", rr.Boxes2D(array=dets.boxes,
                                                array_format=rr.Box2DFormat.XYWH,
                                                colors=detection_colours(dets),
                                                labels=detection_labels(dets),
                                                radii=0.5))
        rec.log("camera/detections/centroids", rr.Points2D(dets.centers, radii=1.5,
                                                            colors=(255, 255, 255)))
        rec.log("metrics/tracks", rr.Scalars(len(ft.ids)))
        rec.log("metrics/detections", rr.Scalars(len(dets.centers)))
        self._log_rows(ft.rows)
        self._log_state(frame.index, ft)
        self.last_frame = frame.index

    def _log_rows(self, rows: np.ndarray) -> None:
        """Each tracks.csv row as the box of entity camera/tracks/<id> at its own frame."""
        for f, tid, x, y, w, h, conf in rows:
            tid = int(tid)
            self.live.add(tid)
            self.rec.set_time("frame", sequence=int(f))
            coast = conf < 1.0
            self.rec.log(f"camera/tracks/{tid}", rr.Boxes2D(
                array=[[x, y, w, h]], array_format=rr.Box2DFormat.XYWH,
                labels=[f"#{tid} coast" if coast else f"#{tid}"],
                colors=[(150, 150, 150) if coast else track_color(tid)],
                radii=[0.5 if coast else 1.5]))

    def _log_state(self, frame: int, ft: Any) -> None:
        rec = self.rec
        rec.set_time("frame", sequence=frame)
        current = {int(i) for i in ft.ids}
        for tid in sorted(self.live - current):   # ended tracks: clear their entities
            rec.log(f"camera/tracks/{tid}", rr.Boxes2D.cleared())
            rec.log(f"camera/trails/{tid}", rr.LineStrips2D.cleared())
            rec.log(f"camera/covariance/{tid}", rr.LineStrips2D.cleared())
        self.live = current
        for k, tid in enumerate(ft.ids):
            tid = int(tid)
            x, P = ft.states[k], ft.covariances[k]
            color = track_color(tid)
            rec.log(f"camera/covariance/{tid}",
                    rr.LineStrips2D([ellipse_points(x[:2], P[:2, :2])], colors=[color],
                                    radii=0.5))
            rec.log(f"tracks/{tid}/speed", rr.Scalars(float(np.hypot(x[2], x[3]))))
            rec.log(f"tracks/{tid}/acceleration", rr.Scalars(float(np.hypot(x[4], x[5]))))
            if np.isfinite(ft.innovations[k]):
                rec.log(f"tracks/{tid}/innovation", rr.Scalars(float(ft.innovations[k])))

    def log_trails(self, trails: dict[int, list[tuple[float, float]]]) -> None:
        for tid, pts in trails.items():
            if tid in self.live and len(pts) > 1:
                self.rec.log(f"camera/trails/{tid}", rr.LineStrips2D([pts],
                                                                     colors=[track_color(tid)]))

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()


# ------------------------------------------------------------- estimation runs


def _log_series(rec: Any, name: str, times: np.ndarray, values: np.ndarray) -> None:
    rec.send_columns(name, indexes=[rr.TimeColumn("time", duration=times)],
                     columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=float)))


def log_experiment(result: Any, name: str, path: str | Path) -> None:
    """An experiment's example run: truth and each filter's estimate in the plane, sensors
    (and bearing rays), 2-sigma ellipses, and position error and NEES over time."""
    ex = result.example
    if ex is None:
        raise ValueError(f"experiment {name} has no example run to log")
    spatial = (rrb.Spatial3DView(name="world", origin="/world") if ex.truth.shape[1] == 3
               else rrb.Spatial2DView(name="plane", origin="/plane"))
    bp = rrb.Blueprint(rrb.Horizontal(
        spatial,
        rrb.Vertical(rrb.TimeSeriesView(name="position error", origin="/error"),
                     rrb.TimeSeriesView(name="NEES", origin="/nees"),
                     rrb.TimeSeriesView(name="series", origin="/series"))))
    rec = _open(f"vtrack-experiment-{name}", path, bp)
    i, j = ex.position
    truth = np.asarray(ex.truth)[:, [i, j]]
    rec.log("plane/truth", rr.LineStrips2D([truth], colors=(255, 255, 255), labels=["truth"]),
            static=True)
    if ex.sensors is not None:
        rec.log("plane/sensors", rr.Points2D(ex.sensors, radii=0.05, colors=(255, 200, 0),
                                             labels=[f"S{k + 1}" for k in range(len(ex.sensors))]),
                static=True)
    for k, (kind, est) in enumerate(ex.estimates.items()):
        color = track_color(k + 1)
        est = np.asarray(est)
        rec.log(f"plane/{kind}/path", rr.LineStrips2D([est[:, [i, j]]], colors=[color],
                                                     labels=[kind]), static=True)
        err = np.hypot(est[:, i] - ex.truth[:, i], est[:, j] - ex.truth[:, j])
        _log_series(rec, f"error/{kind}", ex.times, err)
        if kind in ex.nees:
            _log_series(rec, f"nees/{kind}", ex.times, ex.nees[kind])
        covs = ex.covariances.get(kind)
        step = max(1, len(ex.times) // 200)
        for t_idx in range(0, len(ex.times), step):
            rec.set_time("time", duration=float(ex.times[t_idx]))
            rec.log(f"plane/{kind}/estimate", rr.Points2D([est[t_idx, [i, j]]], colors=[color],
                                                          radii=0.02))
            if covs is not None:
                P = np.asarray(covs[t_idx])[np.ix_([i, j], [i, j])]
                rec.log(f"plane/{kind}/ellipse",
                        rr.LineStrips2D([ellipse_points(est[t_idx, [i, j]], P)], colors=[color]))
            rec.log("plane/truth/now", rr.Points2D([truth[t_idx]], radii=0.03))
            if ex.sensors is not None and ex.measurements is not None \
                    and ex.measurements.shape[1] == len(ex.sensors):
                rays = [[s, s + 10.0 * np.array([np.cos(b), np.sin(b)])]
                        for s, b in zip(ex.sensors, ex.measurements[t_idx])]
                rec.log("plane/bearings", rr.LineStrips2D(rays, colors=(255, 200, 0), radii=0.005))
    if ex.truth.shape[1] == 3:   # a 3-D trajectory (ins): paths, and fixes if given
        rec.log("world/truth", rr.LineStrips3D([ex.truth], colors=(255, 255, 255)), static=True)
        for k, (kind, est) in enumerate(ex.estimates.items()):
            rec.log(f"world/{kind}", rr.LineStrips3D([np.asarray(est)[:, :3]],
                                                     colors=[track_color(k + 1)]), static=True)
        fixes = None if ex.measurements is None else np.asarray(ex.measurements, dtype=float)
        if fixes is not None and fixes.ndim == 2 and fixes.shape[1] >= 3:
            fixes = fixes[np.all(np.isfinite(fixes[:, :3]), axis=1), :3]
            rec.log("world/fixes", rr.Points3D(fixes, radii=0.5, colors=(255, 200, 0)),
                    static=True)
    for key, series in ex.extra_series.items():
        key = re.sub(r"[^A-Za-z0-9_/.-]+", "_", key).strip("_")
        series = np.asarray(series, dtype=float)
        if len(series) != len(ex.times):
            continue
        if series.ndim == 1:
            _log_series(rec, f"series/{key}", ex.times, series)
        elif series.ndim == 2:
            for c in range(series.shape[1]):
                _log_series(rec, f"series/{key}/{c}", ex.times, series[:, c])
    rec.flush()
    rec.disconnect()


def log_filter_run(times: np.ndarray, estimates: np.ndarray, covariances: np.ndarray,
                   measurements: np.ndarray, sensors: np.ndarray | None,
                   path: str | Path) -> None:
    """A `vtrack filter` run: the estimated path, 2-sigma ellipses, state components over time."""
    bp = rrb.Blueprint(rrb.Horizontal(rrb.Spatial2DView(name="plane", origin="/plane"),
                                      rrb.TimeSeriesView(name="state", origin="/state")))
    rec = _open("vtrack-filter", path, bp)
    est = np.asarray(estimates)
    rec.log("plane/estimate/path", rr.LineStrips2D([est[:, :2]]), static=True)
    if sensors is not None:
        rec.log("plane/sensors", rr.Points2D(sensors, radii=0.05, colors=(255, 200, 0)),
                static=True)
    for k in range(est.shape[1]):
        _log_series(rec, f"state/x{k}", times, est[:, k])
    for t, x, P in zip(times, est, covariances):
        rec.set_time("time", duration=float(t))
        rec.log("plane/estimate/ellipse", rr.LineStrips2D([ellipse_points(x[:2], P[:2, :2])]))
    rec.flush()
    rec.disconnect()


# detection colours by provenance (vision/fusion.py): motion grey, appearance orange, both cyan
PROVENANCE_RGB = np.array([(200, 200, 200), (255, 140, 0), (0, 255, 255)], dtype=np.uint8)


def detection_colours(dets: Any) -> np.ndarray:
    """(K, 3) RGB per detection: its provenance's colour."""
    return PROVENANCE_RGB[np.asarray(dets.source, dtype=int)]


def detection_labels(dets: Any) -> list[str]:
    """Per detection: its provenance, and for an appearance box its class and score."""
    from vtrack.vision.appearance import VEHICLE_CLASSES
    from vtrack.vision.fusion import PROVENANCE

    return [PROVENANCE[s] if c < 0 else f"{PROVENANCE[s]} {VEHICLE_CLASSES[c]} {p:.2f}"
            for s, c, p in zip(dets.source.tolist(), dets.cls.tolist(), dets.score.tolist())]
