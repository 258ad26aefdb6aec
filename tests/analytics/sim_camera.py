"""A perspective traffic camera with exact world ground truth, for the speed/length/class tests.

A pinhole camera on a mast (height `cam_height` m, over the road's centre line, `cam_back` m
behind the first visible metres) looks along a straight four-lane road: Y is along the road,
X across, Z up (metres). Vehicles are cuboids (length, width, height) in their lanes; two lanes
drive towards the camera (-Y), two away (+Y), each vehicle at its own speed that varies
smoothly, v(t) = v0 (1 + a sin(2 pi t / T + phi)). A vehicle's image box is the bounding box
of its 8 projected corners clipped to the image -- what a perfect detector of the whole
vehicle (body and height) would give.

`detections(n)` gives the boxes of frame n (with optional pixel noise) for the real Tracker;
`render(out_dir)` paints the scene into a video (road, lane marks, shaded cuboids drawn far
to near) and writes the files of `vtrack synth --scene mast`: video.avi, gt.csv, world.csv
and calibration.toml.

    python tests/analytics/sim_camera.py OUT_DIR [--seed S] [--frames N] [--vehicles K]
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

KINDS = {  # probability, length, width, height ranges (m), speed range (km/h)
    "motorcycle": (0.10, (2.0, 2.4), (0.8, 0.9), (1.3, 1.5), (40, 80)),
    "car": (0.50, (3.9, 4.9), (1.7, 1.9), (1.4, 1.6), (45, 100)),
    "van": (0.22, (5.3, 6.6), (2.0, 2.2), (2.0, 2.6), (45, 90)),
    "truck": (0.18, (8.5, 12.0), (2.5, 2.55), (3.2, 4.0), (40, 80)),
}
LANES = ((-5.25, -1), (-1.75, -1), (1.75, 1), (5.25, 1))   # lane centre X, direction along Y
ROAD_HALF = 7.0
Y_NEAR, Y_FAR = -5.0, 140.0                                  # where vehicles appear/vanish


@dataclass(frozen=True)
class Camera:
    K: np.ndarray
    R: np.ndarray       # world -> camera
    C: np.ndarray       # centre, world
    width: int
    height: int

    @classmethod
    def mast(cls, width: int = 640, height: int = 360, cam_height: float = 9.0,
             cam_x: float = 0.0, look_y: float = 38.0, hfov_deg: float = 55.0) -> "Camera":
        f = (width / 2) / math.tan(math.radians(hfov_deg) / 2)
        K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1.0]])
        C = np.array([cam_x, 0.0, cam_height])
        fwd = np.array([0.0, look_y, 0.0]) - C
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        return cls(K, np.stack([right, down, fwd]), C, width, height)

    def project(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points (..., 3) -> pixels (..., 2) and depths (...)."""
        Xc = (np.asarray(X, dtype=float) - self.C) @ self.R.T
        uv = Xc @ self.K.T
        return uv[..., :2] / uv[..., 2:3], Xc[..., 2]

    def ground_to_image(self) -> np.ndarray:
        """G = K [r1 r2 t]: road (X, Y, 1) -> image."""
        t = -self.R @ self.C
        return self.K @ np.column_stack([self.R[:, 0], self.R[:, 1], t])

    def image_to_ground(self) -> np.ndarray:
        H = np.linalg.inv(self.ground_to_image())
        return H / H[2, 2]


@dataclass(frozen=True)
class Vehicle:
    id: int
    kind: str
    length: float
    width: float
    height: float
    lane: int
    enter_t: float
    v0: float           # m/s
    wobble: float       # relative speed amplitude
    period: float
    phase: float
    colour: tuple[int, int, int]

    def speed(self, t: np.ndarray) -> np.ndarray:
        return self.v0 * (1 + self.wobble * np.sin(2 * np.pi * t / self.period + self.phase))

    def travelled(self, t: np.ndarray) -> np.ndarray:
        """Distance driven since entering (closed form of the integral of speed)."""
        tau = np.maximum(np.asarray(t, dtype=float) - self.enter_t, 0.0)
        w = 2 * np.pi / self.period
        t0 = self.enter_t
        return self.v0 * (tau - self.wobble / w * (np.cos(w * (t0 + tau) + self.phase)
                                                   - np.cos(w * t0 + self.phase)))

    def centre(self, t: float) -> np.ndarray:
        """Footprint centre (X, Y) at time t."""
        x, direction = LANES[self.lane]
        s = float(self.travelled(t))
        y = (Y_FAR - s) if direction < 0 else (Y_NEAR + s)
        return np.array([x, y])

    def corners(self, t: float) -> np.ndarray:
        """(8, 3) corners of the cuboid at time t."""
        cx, cy = self.centre(t)
        dx, dy = self.width / 2, self.length / 2
        return np.array([[cx + sx * dx, cy + sy * dy, z] for z in (0.0, self.height)
                         for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])

    def on_road(self, t: float) -> bool:
        y = self.centre(t)[1]
        return t >= self.enter_t and Y_NEAR - 1 <= y <= Y_FAR + 1


@dataclass
class Scene:
    camera: Camera
    vehicles: list[Vehicle]
    fps: float
    frames: int

    @classmethod
    def make(cls, seed: int = 0, frames: int = 300, vehicles: int = 10, fps: float = 25.0,
             width: int = 640, height: int = 360, kinds: tuple[str, ...] | None = None,
             wobble: float = 0.08) -> "Scene":
        rng = np.random.default_rng(seed)
        names = list(kinds or KINDS)
        p = np.array([KINDS[k][0] for k in names])
        fleet = []
        duration = frames / fps
        course = Y_FAR - Y_NEAR
        last: dict[int, tuple[float, float, float]] = {}        # lane -> enter, speed, length
        order = rng.permutation(np.resize(np.arange(len(LANES)), vehicles))
        for i in range(vehicles):
            kind = names[rng.choice(len(names), p=p / p.sum())]
            _, L, W, H, V = KINDS[kind]
            lane = int(order[i])
            v0 = rng.uniform(*V) / 3.6
            length = rng.uniform(*L)
            enter = rng.uniform(-4.0, 0.6 * duration)
            if lane in last:   # keep 8 m behind the leader all the way (1 s of margin)
                t_l, v_l, L_l = last[lane]
                enter = max(enter, t_l + (L_l + 8) / v_l + 1.0,
                            t_l + course / v_l - (course - L_l - 8) / v0 + 1.0)
            last[lane] = (enter, v0, length)
            colour = tuple(int(c) for c in rng.choice(
                [(40, 40, 190), (190, 60, 30), (30, 140, 230), (30, 30, 30), (240, 240, 240),
                 (50, 150, 40), (160, 40, 140), (0, 200, 230)]))
            fleet.append(Vehicle(i + 1, kind, length, rng.uniform(*W), rng.uniform(*H),
                                 lane, enter, v0, wobble * rng.uniform(0.5, 1.0),
                                 rng.uniform(4.0, 8.0), rng.uniform(0, 2 * np.pi), colour))
        return cls(Camera.mast(width, height), fleet, fps, frames)

    def time(self, n: int) -> float:
        return (n - 1) / self.fps

    def boxes(self, n: int) -> list[tuple[Vehicle, np.ndarray, float]]:
        """(vehicle, box x, y, w, h clipped, visible fraction) of the vehicles in frame n."""
        t = self.time(n)
        out = []
        for v in self.vehicles:
            if not v.on_road(t):
                continue
            uv, depth = self.camera.project(v.corners(t))
            if np.any(depth <= 0.5):
                continue
            x0, y0 = uv.min(axis=0)
            x1, y1 = uv.max(axis=0)
            cx0, cy0 = max(x0, 0.0), max(y0, 0.0)
            cx1, cy1 = min(x1, self.camera.width), min(y1, self.camera.height)
            if cx1 - cx0 < 1 or cy1 - cy0 < 1:
                continue
            frac = (cx1 - cx0) * (cy1 - cy0) / ((x1 - x0) * (y1 - y0))
            out.append((v, np.array([cx0, cy0, cx1 - cx0, cy1 - cy0]), frac))
        return out

    def detections(self, n: int, rng: np.random.Generator | None = None, noise_px: float = 0.0,
                   min_area: float = 150.0) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """(centres, boxes, vehicle ids) a detector would give in frame n: boxes of at least
        `min_area` px, edges jittered by `noise_px`."""
        boxes, ids = [], []
        for v, b, _ in self.boxes(n):
            if b[2] * b[3] < min_area:
                continue
            if rng is not None and noise_px > 0:
                e = rng.normal(0, noise_px, 4)
                b = np.array([b[0] + e[0], b[1] + e[1], b[2] + e[2] - e[0], b[3] + e[3] - e[1]])
            boxes.append(b)
            ids.append(v.id)
        boxes_a = np.array(boxes).reshape(-1, 4)
        return boxes_a[:, :2] + boxes_a[:, 2:] / 2, boxes_a, ids

    def exact_tracks(self, n: int, eps: float = 1e-3):
        """FrameTracks of a perfect tracker in frame n: every vehicle wholly in view, its box,
        the exact velocity of the box centre and rate of the box size (central differences of
        the projection) known exactly (zero covariance), all detected, every row final."""
        from vtrack.tracking.tracker import FrameTracks

        t = self.time(n)
        ids, boxes, states, rates = [], [], [], []
        for v, b, frac in self.boxes(n):
            if frac < 1:
                continue
            b0, b1 = (self._box_at(v, t + d) for d in (-eps, eps))
            centre = lambda bb: bb[:2] + bb[2:] / 2  # noqa: E731
            ids.append(v.id)
            boxes.append(b)
            states.append([*centre(b), *(centre(b1) - centre(b0)) / (2 * eps), 0.0, 0.0])
            rates.append((b1[2:] - b0[2:]) / (2 * eps))
        k = len(ids)
        boxes_a = np.array(boxes).reshape(-1, 4)
        rows = np.column_stack([np.full(k, n), ids, boxes_a, np.ones(k)]).reshape(-1, 7)
        return FrameTracks(ids=np.array(ids, dtype=int), boxes=boxes_a,
                           coasted=np.zeros(k, dtype=bool), states=np.array(states).reshape(-1, 6),
                           covariances=np.zeros((k, 6, 6)), innovations=np.zeros(k),
                           rows=rows, detection_of=np.zeros(k, dtype=int),
                           size_rates=np.array(rates).reshape(-1, 2))

    def _box_at(self, v: Vehicle, t: float) -> np.ndarray:
        uv, _ = self.camera.project(v.corners(t))
        return np.r_[uv.min(axis=0), uv.max(axis=0) - uv.min(axis=0)]

    # ------------------------------------------------------------------ files
    def calibration_toml(self) -> str:
        """Six road points (lane edges at three distances) in the CALIB.toml format."""
        world = [(-ROAD_HALF, 12.0), (ROAD_HALF, 12.0), (-ROAD_HALF, 30.0), (ROAD_HALF, 30.0),
                 (-3.5, 60.0), (3.5, 60.0)]
        uv, _ = self.camera.project(np.array([[x, y, 0.0] for x, y in world]))
        lines = [f"frame_size = [{self.camera.width}, {self.camera.height}]", ""]
        for (u, v), (x, y) in zip(uv, world):
            lines += ["[[points]]", f"image = [{u:.3f}, {v:.3f}]", f"world = [{x}, {y}]", ""]
        return "\n".join(lines)

    def ground_truth(self) -> tuple[list[list], list[list]]:
        """gt.csv rows (MOT + visible fraction) and world.csv rows."""
        gt, world = [], []
        for n in range(1, self.frames + 1):
            t = self.time(n)
            for v, b, frac in self.boxes(n):
                gt.append([n, v.id, *(f"{x:.2f}" for x in b), 1, -1, -1, -1, f"{frac:.4f}"])
                X, Y = v.centre(t)
                world.append([n, v.id, f"{X:.3f}", f"{Y:.3f}", f"{3.6 * float(v.speed(t)):.3f}",
                              f"{v.length:.3f}", v.kind])
        return gt, world

    def background(self) -> np.ndarray:
        cam = self.camera
        img = np.empty((cam.height, cam.width, 3), np.uint8)
        img[:] = (70, 120, 80)                                   # grass
        G = cam.ground_to_image()

        def poly(pts: list[tuple[float, float]]) -> np.ndarray:
            q = np.array([[x, y, 1.0] for x, y in pts]) @ G.T
            return np.round(q[:, :2] / q[:, 2:3] * 8).astype(np.int32)   # 3 bits of subpixel

        def fill(pts: list[tuple[float, float]], colour: tuple[int, int, int]) -> None:
            cv2.fillPoly(img, [poly(pts)], colour, cv2.LINE_AA, shift=3)

        far = 400.0
        fill([(-ROAD_HALF, 0.5), (ROAD_HALF, 0.5), (ROAD_HALF, far), (-ROAD_HALF, far)],
             (105, 105, 110))
        sky = int(np.clip(cam.project(np.array([0.0, 1e4, 0.0]))[0][1], 0, cam.height))
        img[:sky] = (200, 170, 140)
        for x in (-ROAD_HALF + 0.3, ROAD_HALF - 0.3):
            fill([(x - 0.08, 0.5), (x + 0.08, 0.5), (x + 0.08, far), (x - 0.08, far)],
                 (220, 220, 220))
        for x in (-3.5, 3.5):
            for y in np.arange(1.0, far, 9.0):
                fill([(x - 0.08, y), (x + 0.08, y), (x + 0.08, y + 3), (x - 0.08, y + 3)],
                     (220, 220, 220))
        fill([(-0.15, 0.5), (0.15, 0.5), (0.15, far), (-0.15, far)], (40, 190, 220))
        return img

    def frame(self, n: int, background: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        img = background.copy()
        t = self.time(n)
        visible = [v for v in self.vehicles if v.on_road(t)]
        visible.sort(key=lambda v: -np.linalg.norm(np.append(v.centre(t), 0) - self.camera.C))
        faces = ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6),
                 (3, 0, 4, 7))
        shade = (0.55, 1.0, 0.75, 0.65, 0.85, 0.65)
        for v in visible:
            X = v.corners(t)
            uv, depth = self.camera.project(X)
            if np.any(depth <= 0.5):
                continue
            centre = X.mean(axis=0)
            order = sorted(range(6), key=lambda f: -np.linalg.norm(
                X[list(faces[f])].mean(axis=0) - self.camera.C))
            for f in order:
                fc = X[list(faces[f])].mean(axis=0)
                if np.dot(fc - centre, self.camera.C - fc) <= 0:
                    continue                                   # faces away from the camera
                colour = tuple(int(c * shade[f]) for c in v.colour)
                pts = np.round(uv[list(faces[f])] * 8).astype(np.int32)
                cv2.fillConvexPoly(img, pts, colour, cv2.LINE_AA, shift=3)
        noise = rng.normal(0, 2.0, img.shape)
        return np.clip(img + noise, 0, 255).astype(np.uint8)

    def render(self, out: Path, seed: int = 0) -> None:
        """video.avi (MJPG), gt.csv, world.csv and calibration.toml into `out`."""
        out.mkdir(parents=True, exist_ok=True)
        bg = self.background()
        rng = np.random.default_rng(seed + 1000)
        w = cv2.VideoWriter(str(out / "video.avi"), cv2.CAP_OPENCV_MJPEG,
                            cv2.VideoWriter_fourcc(*"MJPG"), self.fps,
                            (self.camera.width, self.camera.height))
        w.set(cv2.VIDEOWRITER_PROP_QUALITY, 92)
        for n in range(1, self.frames + 1):
            w.write(self.frame(n, bg, rng))
        w.release()
        gt, world = self.ground_truth()
        (out / "gt.csv").write_text("".join(",".join(map(str, r)) + "\n" for r in gt))
        (out / "world.csv").write_text(
            "frame,id,X_m,Y_m,speed_kmh,length_m,class\n"
            + "".join(",".join(map(str, r)) + "\n" for r in world))
        (out / "calibration.toml").write_text(self.calibration_toml())


class BoxFilter:
    """Stand-in for a tracker that filters the box size: per vehicle one constant-acceleration
    Kalman filter of the shared core on (x, y, w, h) (the box centre and size with their rates),
    updated with the detected box and coasting on its prediction when there is none. Emits
    FrameTracks like vtrack.tracking.Tracker (ids = the vehicles' ids, every row final)."""

    def __init__(self, jerk_psd: float = 1e4, noise_px: float = 1.0) -> None:
        from vtrack.estimation.models import ConstantAcceleration

        self.model = ConstantAcceleration(jerk_psd, dim=4)
        self.R = np.eye(4) * noise_px ** 2
        self.H = np.eye(4, 12)
        self.x: dict[int, np.ndarray] = {}
        self.P: dict[int, np.ndarray] = {}
        self.t: float | None = None

    def step(self, frame: int, t: float, boxes: np.ndarray, ids: list[int]):
        from vtrack.estimation.kalman import kf_predict, kf_update
        from vtrack.tracking.tracker import FrameTracks

        dt = 0.0 if self.t is None else t - self.t
        self.t = t
        z_of = {vid: np.r_[b[:2] + b[2:] / 2, b[2:]] for vid, b in zip(ids, boxes)}
        for vid in list(self.x):
            if dt > 0:
                self.x[vid], self.P[vid] = kf_predict(self.x[vid], self.P[vid],
                                                      self.model.transition(dt), self.model.Q(dt))
        for vid, z in z_of.items():
            if vid not in self.x:
                self.x[vid] = np.r_[z, np.zeros(8)]
                self.P[vid] = np.diag([4.0] * 4 + [200.0 ** 2] * 4 + [100.0 ** 2] * 4)
            else:
                self.x[vid], self.P[vid], _ = kf_update(self.x[vid], self.P[vid],
                                                        z - self.H @ self.x[vid], self.H, self.R)
        vids = sorted(self.x)
        keep = [0, 1, 4, 5, 8, 9]                        # x, y, vx, vy, ax, ay
        X = np.array([self.x[v] for v in vids]).reshape(-1, 12)
        P = np.array([self.P[v][np.ix_(keep, keep)] for v in vids]).reshape(-1, 6, 6)
        boxes_f = np.column_stack([X[:, 0] - X[:, 2] / 2, X[:, 1] - X[:, 3] / 2, X[:, 2:4]])
        coasted = np.array([v not in z_of for v in vids], dtype=bool)
        rows = np.column_stack([np.full(len(vids), frame), vids, boxes_f,
                                np.where(coasted, 0.5, 1.0)]).reshape(-1, 7)
        return FrameTracks(ids=np.array(vids, dtype=int), boxes=boxes_f, coasted=coasted,
                           states=X[:, keep], covariances=P, innovations=np.zeros(len(vids)),
                           rows=rows, detection_of=np.zeros(len(vids), dtype=int),
                           size_rates=X[:, 6:8])

    def drop(self, vid: int) -> None:
        self.x.pop(vid, None)
        self.P.pop(vid, None)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--vehicles", type=int, default=10)
    a = p.parse_args()
    Scene.make(a.seed, a.frames, a.vehicles).render(a.out, a.seed)


if __name__ == "__main__":
    main()
