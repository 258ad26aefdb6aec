"""Tracker parameters ([tracker] in the TOML config), each documented where it is declared.

Scale-free: lengths are in box scales (the box scale of a track is sqrt(w h) of its box, in
px) and durations in seconds, so one default serves 320x240 and 1920x1080 video, 24 and 60
fps, and both ends of a perspective view where a vehicle's size changes several times.
"""

from __future__ import annotations

from dataclasses import dataclass, field

ADAPTIVE_KINDS = ("ankf1", "ankf2", "fuzzy-r", "fuzzy-q", "siim-ekf")
MEASUREMENTS = ("finite-difference", "finite-difference-white", "position")


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
        "(seed 001 eqs. 24-26) with the errors of the detections they share carried in the "
        "state (consistent); 'finite-difference-white': the seed's H = I6 with white "
        "R = D Sigma D' (overconfident: its rows are correlated in time); 'position': "
        "position only"))
    jerk: float = field(default=10.0, metadata=_h(
        "white-jerk spectral density of the constant-acceleration model, box scales^2/s^5 "
        "(q_j = jerk * L^2 px^2/s^5 for a box of scale L px)"))
    detection_sigma: float = field(default=0.06, metadata=_h(
        "std of a detected centre, box scales (at least 0.5 px)"))
    coast_accel_rate: float = field(default=0.0, metadata=_h(
        "decay rate of a coasting track's acceleration, 1/s (Singer's Markov acceleration, "
        "models.singer_transition): while no detection updates a track, its acceleration "
        "decays as exp(-rate dt); 0: constant acceleration; inf: constant velocity"))
    init_speed_sigma: float = field(default=5.0, metadata=_h(
        "prior std of a new track's velocity, box scales/s"))
    init_accel_sigma: float = field(default=3.0, metadata=_h(
        "prior std of a new track's acceleration, box scales/s^2"))
    gate_probability: float = field(default=0.999, metadata=_h(
        "chi-square gate on the predicted position (2 dof)"))
    max_gate: float = field(default=2.5, metadata=_h(
        "upper bound of the gate's Euclidean radius, box scales"))
    scale_field: bool = field(default=True, metadata=_h(
        "learn how a vehicle's image size changes with its position (scale_field.py) and "
        "predict each box's growth from its motion; false: sizes change only by their rates"))
    own_size: bool = field(default=True, metadata=_h(
        "a detection the size of the vehicle's own (the median of its last detections, "
        "carried along the scale field) restarts its box at once, where the size gate would "
        "hold a merged or wrong size for `size_shrink_seconds` (box_size.py); false: only "
        "the gate's waits do"))
    size_psd: float = field(default=0.01, metadata=_h(
        "white-noise acceleration density of the log box size, 1/s^3 (box_size.py)"))
    size_rate_seconds: float = field(default=1.0, metadata=_h(
        "time constant of the size rates' return to zero without measurements, s"))
    size_sigma: float = field(default=0.08, metadata=_h(
        "relative std of a detected box side"))
    size_gate_probability: float = field(default=0.997, metadata=_h(
        "a detected side outside this chi-square gate (1 dof) of the predicted size is a "
        "partial view or a merge: it does not update the size (box_size.py)"))
    size_grow_seconds: float = field(default=0.0, metadata=_h(
        "detections larger than the size gate for this long restart the size from them, s "
        "(0: at once; a track often starts on part of a vehicle coming into view)"))
    size_shrink_seconds: float = field(default=1.0, metadata=_h(
        "detections smaller than the size gate for this long restart the size from them, s"))
    shrink_unexplained: bool = field(default=False, metadata=_h(
        "a detected side smaller than the size gate restarts the size at once (not after "
        "`size_shrink_seconds`) when nothing shows the detection to be a partial view: not "
        "anchored on a static occluder's edge, not cut by the border, overlapping no other "
        "track's box (sizes.py); for detectors whose boxes are whole. Off: it costs real "
        "counts on MOG2's blobs (docs/TRACKER.md)"))
    init_size_rate_sigma: float = field(default=0.05, metadata=_h(
        "prior std of a new track's relative size rate d ln w/dt, 1/s"))
    confirm_seconds: float = field(default=0.3, metadata=_h(
        "confirmation window, s: a track is confirmed once detected in `confirm_fraction` "
        "of the frames of the last `confirm_seconds` (a track's rows from before are "
        "back-filled)"))
    confirm_fraction: float = field(default=0.75, metadata=_h(
        "share of the confirmation window's frames with a detection"))
    confirm_motion: float = field(default=0.5, metadata=_h(
        "a track is confirmed only once an edge of its detected box has moved this many box "
        "scales from where it was first seen: a vehicle moves, swaying leaves and flicker "
        "stay put (0 turns the check off)"))
    max_coast_seconds: float = field(default=1.0, metadata=_h(
        "time a confirmed track coasts on its prediction without a detection before it is "
        "deleted, s"))
    reid_seconds: float = field(default=3.0, metadata=_h(
        "a confirmed track lost in view (undetected for `max_coast_seconds`) is remembered "
        "for this long after its last detection: a track that continues it takes its id "
        "(reidentifier.py; 0: off), s"))
    reid_gate: float = field(default=1.0, metadata=_h(
        "a continuing track's centre lies within this many box scales of the lost track's "
        "prediction, plus half the way that prediction went since its last detection"))
    reid_scale_ratio: float = field(default=2.0, metadata=_h(
        "... and its box scale differs from the lost track's by less than this factor"))
    reid_colour: float = field(default=0.7, metadata=_h(
        "... and its colour matches the lost track's: Bhattacharyya coefficient of their "
        "colour signatures at least this (vision/colour.py)"))
    smooth_coasted: bool = field(default=True, metadata=_h(
        "report a coasted stretch that a detection confirms smoothed (fixed-interval RTS "
        "smoother over the predictions, reporter.py), not as the straight prediction"))
    stand_speed: float = field(default=0.8, metadata=_h(
        "a confirmed track that loses its detection while slower than this, its speed's "
        "standard deviation included (box scales/s) "
        "is a standing vehicle -- queued, parked, waiting at a light -- which the background "
        "model absorbs and the motion check drops: it is held where it stopped (0: off)"))
    max_stand_seconds: float = field(default=60.0, metadata=_h(
        "time a standing vehicle is held without a detection, s; when it drives off, the "
        "detection that appears in its box takes it up again (same id)"))
    tentative_coast_seconds: float = field(default=0.1, metadata=_h(
        "time without a detection that deletes a track not yet confirmed, s"))
    split_evidence: float = field(default=0.25, metadata=_h(
        "a track whose box holds two pieces tells one vehicle cut by an occluder (the gap "
        "between the pieces stays put) from several vehicles (the gap moves with them) once "
        "it has moved this far since the pieces appeared, box scales"))
    split_hold_seconds: float = field(default=0.05, metadata=_h(
        "the record of a gap between two pieces survives this long without them (a merged "
        "frame between frames of pieces, as in a detector that flickers between two "
        "vehicles in tandem and their union), s; only while the gap has looked like road "
        "(`gap_changed_share`) and only with the detector's changed map (0: off)"))
    gap_labels: bool = field(default=True, metadata=_h(
        "read the gap between two pieces of a track's blob with MOG2's raw labels (the "
        "detector's changed map, vision/changed.py): body or road (false: by its motion "
        "alone)"))
    gap_changed_share: float = field(default=0.5, metadata=_h(
        "a gap between two pieces of which MOG2 labelled at least this share foreground or "
        "shadow is body (one vehicle, not split); under it the gap is road, and a road gap "
        "that moves with the track on a second frame splits it at once; read only once the "
        "vehicle has moved its own length since its first detection (associator.py)"))
    split_span: float = field(default=1.2, metadata=_h(
        "pieces in one confirmed track's box that together span more than this many times "
        "the track's box (width or height) are separate vehicles at once (associator.py)"))
    gap_follow_share: float = field(default=0.5, metadata=_h(
        "a gap between two pieces that has moved at least this share of the track's travel "
        "since it appeared moved with the vehicles: several vehicles, not an occluder's gap"))
    whole_piece: bool = field(default=False, metadata=_h(
        "of several detections in one confirmed track's box, one that is by itself the "
        "vehicle where it is predicted (both sides in the size gate, IoU >= `blob_fit_iou` "
        "with the predicted box, not cut by the border) makes the others other vehicles: "
        "nothing is joined (fragments.py); for detectors that give whole boxes of vehicles "
        "that overlap. Off: it costs real counts on MOG2's blobs (docs/TRACKER.md)"))
    nested_share: float = field(default=0.9, metadata=_h(
        "a piece lying this share of its area within another is a part of it (a car's "
        "windows in its body): no gap between them"))
    duplicate_overlap: float = field(default=0.5, metadata=_h(
        "tracks whose centres share one detection and whose boxes overlap by more than this "
        "share of the smaller box follow one vehicle: the younger ones are duplicates"))
    duplicate_seconds: float = field(default=0.0, metadata=_h(
        "a duplicate track is deleted once it has been one on every frame for this long, s "
        "(0: at once); two vehicles whose boxes overlap share one detection only while the "
        "other's is missing, two tracks on one vehicle share it on every frame"))
    whole_duplicate_seconds: float = field(default=0.1, metadata=_h(
        "`duplicate_seconds` for a track whose shared detection is a whole box (one the "
        "appearance model drew: provenance.py): two vehicles whose whole boxes overlap share "
        "one only while the other's box is missing, s"))
    small_in_blob: float = field(default=0.25, metadata=_h(
        "the oldest of such tracks whose box covers under this share of the shared blob "
        "follows a smaller vehicle seen over a larger one (a car beside a truck)"))
    blob_fit_iou: float = field(default=0.5, metadata=_h(
        "... and the track whose box matches the blob with at least this IoU (the best) "
        "takes it, none deleted"))
    reacquire_area: float = field(default=2.0, metadata=_h(
        "a track left without a detection takes a left-over detection inside its box whose "
        "area is at most this many times its box's (larger: a merge of several)"))
    gate_candidates: int = field(default=8, metadata=_h(
        "detections nearest each track considered by the gate (a k-d tree query): a gate "
        "holds a few detections at most; a further one in the gate is not considered"))
    box_candidates: int = field(default=8, metadata=_h(
        "points nearest a box's centre tested for lying inside it (pieces in a track's box, "
        "tracks' centres in a blob, left-over detections in a lost track's box, new "
        "detections in a confirmed box): a box holds a few vehicle centres at most; a "
        "further one inside it is not considered"))
    edge_margin: float = field(default=0.0, metadata=_h(
        "a track is deleted once its whole predicted box is this far outside the image, box "
        "scales (a vehicle half out of view keeps its track)"))

    def validate(self) -> None:
        if self.filter not in ("kf",) + ADAPTIVE_KINDS:
            raise ValueError(f"tracker.filter must be one of kf, {', '.join(ADAPTIVE_KINDS)}")
        if self.coast_accel_rate > 0 and self.filter != "kf":
            raise ValueError("tracker.coast_accel_rate needs tracker.filter = 'kf'")
        if self.measurement not in MEASUREMENTS:
            raise ValueError(f"tracker.measurement must be one of {', '.join(MEASUREMENTS)}")
        for name in ("jerk", "detection_sigma", "init_speed_sigma", "init_accel_sigma",
                     "max_gate", "split_evidence", "reid_gate", "size_psd", "size_sigma",
                     "init_size_rate_sigma", "size_rate_seconds", "size_shrink_seconds", "max_stand_seconds", "confirm_seconds", "max_coast_seconds",
                     "tentative_coast_seconds"):
            if not getattr(self, name) > 0:
                raise ValueError(f"tracker.{name} must be positive")
        for name in ("gate_probability", "size_gate_probability"):
            if not 0 < getattr(self, name) < 1:
                raise ValueError(f"tracker.{name} must be in (0, 1)")
        if not 0 < self.confirm_fraction <= 1:
            raise ValueError("tracker.confirm_fraction must be in (0, 1]")
        for name in ("split_span", "reacquire_area"):
            if not getattr(self, name) > 0:
                raise ValueError(f"tracker.{name} must be positive")
        for name in ("gap_follow_share", "nested_share", "duplicate_overlap", "small_in_blob",
                     "blob_fit_iou"):
            if not 0 < getattr(self, name) <= 1:
                raise ValueError(f"tracker.{name} must be in (0, 1]")
        for name in ("gate_candidates", "box_candidates"):
            if not (isinstance(getattr(self, name), int) and getattr(self, name) >= 1):
                raise ValueError(f"tracker.{name} must be an integer >= 1")
        if not 0 < self.reid_colour <= 1:
            raise ValueError("tracker.reid_colour must be in (0, 1]")
        if not self.reid_scale_ratio > 1:
            raise ValueError("tracker.reid_scale_ratio must be > 1")
        if not 0 < self.gap_changed_share <= 1:
            raise ValueError("tracker.gap_changed_share must be in (0, 1]")
        for name in ("confirm_motion", "edge_margin", "size_grow_seconds", "stand_speed",
                     "split_hold_seconds", "duplicate_seconds", "whole_duplicate_seconds",
                     "coast_accel_rate", "reid_seconds"):
            if getattr(self, name) < 0:
                raise ValueError(f"tracker.{name} must be >= 0")
