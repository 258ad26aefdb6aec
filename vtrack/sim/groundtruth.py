"""Ground truth of the perspective scenes: MOT rows from the rendered silhouettes, the road-plane
positions (world.csv) and the camera calibration (calibration.toml).

A vehicle's box is the bounding box of its projected body (the union of its blocks' convex
hulls, without its shadow), clipped to the image; its visible fraction is the number of pixels
it owns in the final id buffer (after nearer vehicles, street furniture, tree crowns and the
image border took theirs) over the area of its whole silhouette.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np

from vtrack.sim.camera import Camera

WORLD_HEADER = "frame,id,X_m,Y_m,speed_kmh,length_m,class\n"


@dataclass(frozen=True)
class Seen:
    """One vehicle in one frame: its index, silhouette area (pixels) and box (x0, y0, x1, y1;
    x1, y1 exclusive) in the coordinates of the id buffer it was drawn into, and the centre
    of its footprint on the road (m)."""

    vehicle: int
    area: float
    box: tuple[int, int, int, int]
    centre: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class Row:
    """A vehicle at least partly in view: index, box clipped to the image, visible fraction
    and footprint centre on the road."""

    vehicle: int
    left: int
    top: int
    width: int
    height: int
    visible: float
    centre: tuple[float, float]


def frame_rows(seen: list[Seen], ids: np.ndarray, origin: tuple[int, int]) -> list[Row]:
    """The rows of the vehicles at least partly inside the image `ids` (the id buffer
    cropped at `origin` of the drawing buffer; a vehicle's id there is its index + 1)."""
    h, w = ids.shape
    rows = []
    for s in seen:
        x0, y0 = max(s.box[0] - origin[0], 0), max(s.box[1] - origin[1], 0)
        x1, y1 = min(s.box[2] - origin[0], w), min(s.box[3] - origin[1], h)
        if x1 > x0 and y1 > y0 and s.area > 0:
            owned = cv2.countNonZero(cv2.compare(ids[y0:y1, x0:x1], s.vehicle + 1, cv2.CMP_EQ))
            rows.append(Row(s.vehicle, x0, y0, x1 - x0, y1 - y0, min(1.0, owned / s.area),
                            s.centre))
    return rows


class IdBook:
    """Ground-truth ids 1, 2, ... in the order vehicles first appear (ties by index)."""

    def __init__(self) -> None:
        self.ids: dict[int, int] = {}

    def __call__(self, vehicle: int) -> int:
        """The id of a vehicle index, giving it the next one on first sight."""
        if vehicle not in self.ids:
            self.ids[vehicle] = len(self.ids) + 1
        return self.ids[vehicle]


def format_world(rows: list[tuple[int, int, float, float, float, float, str]]) -> str:
    """world.csv text: header, then frame,id,X_m,Y_m,speed_kmh,length_m,class rows."""
    return WORLD_HEADER + "".join(f"{f},{i},{x:.3f},{y:.3f},{v:.2f},{length:.2f},{c}\n"
                                  for f, i, x, y, v, length, c in rows)


def choose_landmarks(camera: Camera, landmarks: list[tuple[float, float]],
                     margin: float = 0.06) -> np.ndarray:
    """Four road-plane landmarks that project well inside the image and span the largest
    quadrilateral there (so no three are collinear), as an (4, 2) array."""
    pts = np.array(landmarks, float).reshape(-1, 2)
    if len(pts):
        world = np.column_stack([pts, np.zeros(len(pts))])
        cam = camera.to_camera(world)
        ok = cam[:, 2] > 1.0
        px = np.full((len(pts), 2), -1e9)
        px[ok] = camera.pixels(cam[ok])
        inside = ok & (px[:, 0] > margin * camera.width) & (px[:, 0] < (1 - margin) * camera.width)
        inside &= (px[:, 1] > margin * camera.height) & (px[:, 1] < (1 - margin) * camera.height)
        pts, px = pts[inside], px[inside]
    if len(pts) < 4:
        pts, px = _grid_points(camera, margin)
    hull = cv2.convexHull(px.astype(np.float32), returnPoints=False).ravel()
    if len(hull) > 14:
        hull = hull[np.linspace(0, len(hull) - 1, 14).astype(int)]
    best, best_area = None, -1.0
    for quad in itertools.combinations(hull, 4):
        area = _quad_area(px[list(quad)])
        if area > best_area:
            best, best_area = quad, area
    return pts[list(best)]


def _grid_points(camera: Camera, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Fallback landmarks: road-plane points under a grid of pixels in the lower image."""
    u, v = np.meshgrid(np.linspace(margin, 1 - margin, 5) * camera.width,
                       np.linspace(0.45, 1 - margin, 4) * camera.height)
    rays = camera.rays(u.ravel(), v.ravel())
    t = -camera.centre[2] / np.minimum(rays[:, 2], -1e-6)
    pts = camera.centre[:2] + t[:, None] * rays[:, :2]
    return pts, np.column_stack([u.ravel(), v.ravel()])


def _quad_area(q: np.ndarray) -> float:
    """Area of the convex hull of four points (shoelace over their hull order)."""
    c = q.mean(0)
    order = np.argsort(np.arctan2(q[:, 1] - c[1], q[:, 0] - c[0]))
    p = q[order]
    return 0.5 * abs(float(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1))))


def calibration_toml(camera: Camera, world: np.ndarray) -> str:
    """calibration.toml: each road-plane point with its exact pixel in the unshaken camera,
    and the frame size."""
    h = camera.homography()
    lines = ["# Road-plane points (metres) and their pixels (full frame, OpenCV origin), exact\n"
             "# for the synthetic camera before shake. vtrack track --calibration reads this.\n",
             f"frame_size = [{camera.width}, {camera.height}]\n"]
    for x, y in world:
        p = h @ np.array([x, y, 1.0])
        lines.append(f"\n[[points]]\nimage = [{p[0] / p[2]:.3f}, {p[1] / p[2]:.3f}]\n"
                     f"world = [{x:.3f}, {y:.3f}]\n")
    return "".join(lines)
