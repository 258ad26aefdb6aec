"""Per-vehicle figures of vehicles.csv: extent in time, speed, length and class.

Samples (speed, footprint) are taken in the frames where a detection updated the track (a
coasting track's state is a prediction: a brief occlusion adds no samples, so it cannot make
the speed swing), whose box is clear of the image border (a cut box has no true bottom, so
its ground point is wrong) and whose road speed the filter knows to SPEED_SIGMA_MAX (far from
the camera one pixel is metres). A track with no such frame uses its other detected frames.

- speed_mean_kmh: the mean of the per-frame road speeds.
- speed_max_kmh: the largest mean over a sliding window of SPEED_WINDOW_S seconds (one noisy
  frame cannot make the maximum); a track shorter than half the window reports its mean.
- the speed at a moment (a count line's crossing, speeds.csv): SpeedTrace, the road
  displacement of the filtered ground point over CROSSING_WINDOW_S around it, from the track's
  good frames (its other detected frames if it has no good one).
- length_m and class: LengthFit (the footprint along travel, corrected for the height the box
  includes with the class's typical height; class from the length, CLASS_BOUNDS_M).
- the appearance class: the class the appearance model gave the track's detections, their
  scores summed per class (`Looks`). With both, `combined_class`: the appearance model
  decides what length cannot tell apart (bicycle from motorcycle, bus from truck), the
  length decides the rest (car, van, truck: van only from length).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

SPEED_WINDOW_S = 2.0
SPEED_SIGMA_MAX = 3.0         # m/s: a frame whose road speed the filter knows worse (far
                              # away, where a pixel is metres, or a young track) is not used
TRACE_SAMPLES = 512           # frames a track keeps for reading its speed at a moment
CROSSING_WINDOW_S = 1.0       # the speed at a moment: the road displacement over this window
MIN_LENGTH_SPEED = 1.0        # m/s: below this the travel direction is noise (no length sample)

# Upper length bounds of each class, metres (the last is open). Between typical classes:
# motorcycles are 2-2.5 m; cars 3.5-5 m (large saloons reach 5.1); vans and pick-ups 5.2-7 m;
# rigid and articulated trucks and buses from about 7.5 m.
CLASS_BOUNDS_M = (("motorcycle", 3.0), ("car", 5.1), ("van", 7.5), ("truck", math.inf))
CLASSES = tuple(name for name, _ in CLASS_BOUNDS_M)
# Typical heights (roof, or rider's head), metres: they grow with the length classes.
CLASS_HEIGHT_M = {"motorcycle": 1.4, "car": 1.5, "van": 2.3, "truck": 3.6}


# every class a vehicle may have, in the order of the output files (the contract's)
CLASS_ORDER = ("motorcycle", "bicycle", "car", "van", "bus", "truck")
# classes the appearance model tells better than a length does
LOOKS_DECIDE = ("bicycle", "motorcycle", "bus")


def combined_class(metric: str, looks: str) -> str:
    """The class of a vehicle from its length class `metric` and appearance class `looks`
    ('' where unknown): the appearance class for two-wheelers and buses, else the length
    class, else whichever is known."""
    if looks in LOOKS_DECIDE or not metric:
        return looks
    return metric


@dataclass
class Looks:
    """The appearance model's votes for one track: score summed per class."""

    votes: dict[str, float] = field(default_factory=dict)

    def add(self, cls: str, score: float) -> None:
        self.votes[cls] = self.votes.get(cls, 0.0) + score

    def best(self) -> str:
        """The class with the largest summed score ('' with no vote)."""
        return max(self.votes, key=self.votes.__getitem__) if self.votes else ""


@dataclass
class SpeedStats:
    """Running mean and the maximum of a sliding-window mean of a speed series (m/s)."""

    window_s: float = SPEED_WINDOW_S
    n: int = 0
    total: float = 0.0
    max_smoothed: float = -math.inf
    _win: deque = field(default_factory=deque)
    _win_sum: float = 0.0

    def add(self, t: float, v: float) -> None:
        self.n += 1
        self.total += v
        self._win.append((t, v))
        self._win_sum += v
        while t - self._win[0][0] > self.window_s:
            self._win_sum -= self._win.popleft()[1]
        if t - self._win[0][0] >= 0.5 * self.window_s:
            self.max_smoothed = max(self.max_smoothed, self._win_sum / len(self._win))

    @property
    def mean(self) -> float:
        return self.total / self.n if self.n else math.nan

    @property
    def max(self) -> float:
        return self.max_smoothed if self.max_smoothed > -math.inf else self.mean


@dataclass
class SpeedTrace:
    """A track's recent road positions (m) of its ground point, in time order, to read its
    speed at a moment t: the distance between the positions of the samples nearest to
    t - CROSSING_WINDOW_S / 2 and t + CROSSING_WINDOW_S / 2 over their time difference (the
    displacement of the filtered ground point mapped onto the road); with a single sample its
    own speed v = J_H(g) g'. Bounded memory (the last TRACE_SAMPLES)."""

    samples: deque = field(default_factory=lambda: deque(maxlen=TRACE_SAMPLES))

    def add(self, t: float, v: float, position: np.ndarray) -> None:
        """One frame: its time, road speed (m/s) and ground point's road position (m)."""
        self.samples.append((t, v, np.asarray(position, dtype=float)))

    def speed_at(self, t: float) -> tuple[float, bool]:
        """(speed at time t in m/s, whether the window has closed: the value is final)."""
        if not self.samples:
            return math.nan, False
        half = CROSSING_WINDOW_S / 2
        times = np.fromiter((s[0] for s in self.samples), dtype=float, count=len(self.samples))
        i = int(np.argmin(np.abs(times - (t - half))))
        j = int(np.argmin(np.abs(times - (t + half))))
        final = bool(times[-1] >= t + half)
        if j <= i:
            return self.samples[j][1], final
        a, b = self.samples[i][2], self.samples[j][2]
        return float(np.hypot(*(b - a)) / (times[j] - times[i])), final


@dataclass
class LengthFit:
    """The vehicle's length from its frames' (L_flat, k) (ground.py): L_flat = L + H k.

    One box cannot tell a long low vehicle from a short tall one, and the height's effect is
    amplified by k (several camera heights' worth of road behind a vehicle's roof), so H is
    not fitted freely: each class c is tried with its typical height H_c (CLASS_HEIGHT_M),
    giving L_c = sum w (L_flat - H_c k) / sum w, and the class whose own length range holds
    L_c is chosen (heights grow with the length ranges, so at most one class is consistent;
    if none is, the one whose range L_c misses by least). Weights 1 / (1 + k^2)^2 follow the
    footprint's noise: the top of the box lands on the road (d^2 / f h_c) metres per pixel
    away at distance d = h_c k. Without a camera k = 0: the flat footprint, classified by
    its length. Only weighted sums are kept."""

    sw: float = 0.0
    sl: float = 0.0
    sk: float = 0.0

    @property
    def n(self) -> float:
        return self.sw

    def add(self, length_flat: float, k: float) -> None:
        w = 1.0 / (1.0 + k * k) ** 2
        self.sw += w
        self.sl += w * length_flat
        self.sk += w * k

    def estimate(self) -> tuple[float, str]:
        """(length_m, class); (NaN, '') without samples."""
        if self.sw == 0:
            return math.nan, ""
        best: tuple[float, float, str] | None = None
        lower = 0.0
        for name, upper in CLASS_BOUNDS_M:
            length = (self.sl - CLASS_HEIGHT_M[name] * self.sk) / self.sw
            miss = max(lower - length, length - upper, 0.0)
            if best is None or miss < best[0]:
                best = (miss, length, name)
            lower = upper
        return best[1], best[2]


@dataclass
class Samples:
    """Speed and length evidence of one track from one kind of frame."""

    speed: SpeedStats = field(default_factory=SpeedStats)
    length: LengthFit = field(default_factory=LengthFit)
    trace: SpeedTrace = field(default_factory=SpeedTrace)


@dataclass
class VehicleRecord:
    """One track's accumulators while it is alive (O(1) memory however long it lives)."""

    id: int
    first_frame: int
    first_time: float
    last_frame: int = 0
    last_time: float = 0.0
    detected_frames: int = 0
    good: Samples = field(default_factory=Samples)   # clear of the border, speed known well
    other: Samples = field(default_factory=Samples)
    crossings: list = field(default_factory=list)   # [time, line, direction, speed m/s|None]
    looks: Looks = field(default_factory=Looks)

    def add_row(self, frame: int, time: float, detected: bool) -> None:
        self.last_frame, self.last_time = max(self.last_frame, frame), max(self.last_time, time)
        if frame < self.first_frame:
            self.first_frame, self.first_time = frame, time
        self.detected_frames += int(detected)

    def speed_at(self, t: float, final: bool) -> float | None:
        """The road speed (m/s) at time t from the good frames' trace (the other detected
        frames' if there is no good one by the end); None while it may still change."""
        if self.good.trace.samples or not final:
            v, settled = self.good.trace.speed_at(t)
            return v if settled or final else None
        return self.other.trace.speed_at(t)[0]

    def figures(self) -> tuple[float, float, float, str]:
        """(speed_mean_kmh, speed_max_kmh, length_m, class); NaN/'' where unknown."""
        s = self.good if self.good.speed.n else self.other
        length_src = self.good if self.good.length.n else self.other
        length, cls = length_src.length.estimate()
        return 3.6 * s.speed.mean, 3.6 * s.speed.max, length, combined_class(
            cls, self.looks.best())

    def row(self, calibrated: bool) -> list:
        """The vehicles.csv row."""
        head = [self.id, self.first_frame, self.last_frame, f"{self.first_time:.4f}",
                f"{self.last_time:.4f}", self.detected_frames]
        if not calibrated:
            return head + ["", "", "", self.looks.best()]
        mean, mx, length, cls = self.figures()
        fmt = lambda v, d: f"{v:.{d}f}" if math.isfinite(v) else ""  # noqa: E731
        return head + [fmt(mean, 2), fmt(mx, 2), fmt(length, 2), cls]
