"""Tracker parameters ([tracker] in the TOML config), each documented where it is declared."""

from __future__ import annotations

from dataclasses import dataclass, field

ADAPTIVE_KINDS = ("ankf1", "ankf2", "fuzzy-r", "fuzzy-q", "siim-ekf")


def _h(text: str) -> dict:
    return {"help": text}


@dataclass
class TrackerConfig:
    """Tracker parameters ([tracker] in the TOML config)."""

    filter: str = field(default="kf", metadata=_h(
        "per-vehicle filter: 'kf' (all tracks stepped together as arrays, with the "
        "`measurement` below) or an adaptive kind of the core run per track on the position "
        "rows: 'ankf1', 'ankf2', 'fuzzy-r', 'fuzzy-q', 'siim-ekf'"))
    measurement: str = field(default="finite-difference", metadata=_h(
        "'finite-difference': position + finite-difference velocity and acceleration "
        "(seed 001 eqs. 24-26, H = I6); 'position': position only"))
    jerk_psd: float = field(default=1e4, metadata=_h(
        "white-jerk spectral density q_j of the constant-acceleration model, px^2/s^5"))
    detection_sigma: float = field(default=2.0, metadata=_h(
        "std of a detected centre, px (R of the position rows; the differences follow)"))
    init_speed_sigma: float = field(default=150.0, metadata=_h(
        "prior std of a new track's velocity, px/s"))
    init_accel_sigma: float = field(default=100.0, metadata=_h(
        "prior std of a new track's acceleration, px/s^2"))
    gate_probability: float = field(default=0.999, metadata=_h(
        "chi-square gate on the predicted position (2 dof)"))
    max_gate_px: float = field(default=80.0, metadata=_h(
        "upper bound of the gate's Euclidean radius, px"))
    confirm_hits: int = field(default=6, metadata=_h(
        "M of the M-of-N confirmation (a track's rows from before it are back-filled)"))
    confirm_window: int = field(default=8, metadata=_h("N of the M-of-N confirmation"))
    confirm_motion: float = field(default=0.3, metadata=_h(
        "a track is confirmed only once its detected centre has moved this many box "
        "diagonals from where it was first seen: a vehicle moves, swaying leaves and "
        "flicker stay put (0 turns the check off)"))
    max_coast_seconds: float = field(default=1.0, metadata=_h(
        "time a confirmed track coasts on its prediction without a detection before it is "
        "deleted, s (in time, not frames, so it means the same at 24 and 60 fps)"))
    tentative_misses: int = field(default=3, metadata=_h(
        "misses that delete a track not yet confirmed"))
    size_smoothing: float = field(default=0.5, metadata=_h(
        "weight of a detection that is larger than the track's box in the box size (0..1]"))
    max_size_growth: float = field(default=0.1, metadata=_h(
        "largest relative growth of a track's box per frame (plus the track's displacement, "
        "so a vehicle coming into view at the border can grow)"))
    size_shrink: float = field(default=0.05, metadata=_h(
        "weight of a smaller detection in the box size: small, because a vehicle partly "
        "hidden by an occluder or the image border looks smaller (0..1]"))
    split_evidence_px: float = field(default=8.0, metadata=_h(
        "a track whose box holds two pieces tells one vehicle cut by an occluder (the gap "
        "between the pieces stays put) from several vehicles (the gap moves with them) once "
        "it has moved this far since the pieces appeared, px"))
    edge_margin_px: float = field(default=0.0, metadata=_h(
        "a track is deleted once its whole predicted box is this far outside the image (a "
        "vehicle half out of view keeps its track: the nested-box measurement follows it)"))

    def validate(self) -> None:
        if self.filter not in ("kf",) + ADAPTIVE_KINDS:
            raise ValueError(f"tracker.filter must be one of kf, {', '.join(ADAPTIVE_KINDS)}")
        if self.measurement not in ("finite-difference", "position"):
            raise ValueError("tracker.measurement must be 'finite-difference' or 'position'")
        for name in ("jerk_psd", "detection_sigma", "init_speed_sigma", "init_accel_sigma",
                     "max_gate_px", "split_evidence_px"):
            if not getattr(self, name) > 0:
                raise ValueError(f"tracker.{name} must be positive")
        if not 0 < self.gate_probability < 1:
            raise ValueError("tracker.gate_probability must be in (0, 1)")
        if not 1 <= self.confirm_hits <= self.confirm_window <= 30:
            raise ValueError("tracker needs 1 <= confirm_hits <= confirm_window <= 30")
        if self.confirm_motion < 0:
            raise ValueError("tracker.confirm_motion must be >= 0")
        if self.max_coast_seconds < 0 or self.tentative_misses < 1:
            raise ValueError("tracker.max_coast_seconds >= 0 and tentative_misses >= 1")
        if not (0 < self.size_smoothing <= 1 and 0 < self.size_shrink <= 1):
            raise ValueError("tracker.size_smoothing and size_shrink must be in (0, 1]")
