"""Detector stage: the far band, searched by MOG2 at full resolution (`[detector] far_band`).

A frame wider than `detect_width` is halved before MOG2 (prepare.py): at the far end of a
motorway seen from a bridge a car 20 px wide becomes 10 px, a blob under the noise floor
`min_pixels`. Where the scale field learnt from the tracked vehicles' boxes (sizes.py)
says a vehicle is small at the detection resolution, the top rows of a perspective view, a
second MOG2 detector with every stage of the first (detect.MotionDetector) runs on those
rows of the full-resolution frame, and its blobs replace the first's there.

The band holds the rows where a vehicle's expected side s (sizes.fit_size, at the
horizontal centre of the frame) is under FAR_SIDE sqrt(min_pixels): there a whole
vehicle's blob is at most a few times the noise floor, and a vehicle the colour of the road
(an outline) falls under it. The band's detector keeps the first's settings in scene units
(its `shift_radius` times the downscale factor; its camera motion the first's, rescaled:
stabilise.Following), and its noise floor is in vehicle units: clip(FAR_SHARE s^2,
min_pixels_far, min_pixels) full-resolution pixels, each side at least FAR_SIDE_SHARE s,
with s the first detector's fit when the band is fixed, taken at the frame's centre column
(band_coef) and fixed with it.

It crops the rows [0, rows): the seam, where the first detector takes over (blob centres
at or below it), plus SEAM_MARGIN vehicle sides, so that a vehicle centred above the seam
lies whole in the crop; a band blob cut by the crop's bottom edge is dropped.

The band is fixed once, when the scale field is first fitted, and starts FAR_LAG frames
later: `align` of a frame runs up to two frames ahead of `locate` in other threads
(app/track.py), so the frame the band starts on depends on the frame numbers alone, not on
the threads' timing. Its background is estimated from the band's rows of the last
FAR_SAMPLES frames sampled every FAR_SAMPLE_SECONDS before it starts (background.py, as the
first detector's from the video's first seconds), so vehicles in the band when it starts
leave no ghosts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FAR_SIDE = 2.0      # the band: expected side under this many sqrt(min_pixels) (mask px)
FAR_SHARE = 0.5     # the band's floor: this share of a vehicle's expected box area
FAR_SIDE_SHARE = 0.4   # and each side of a blob at least this share of a vehicle's side
SEAM_MARGIN = 1.0   # the crop reaches this many vehicle sides (at the seam) below it
MIN_ROWS = 16       # a band of fewer full-resolution rows is not worth a detector
MAX_SHARE = 0.5     # the seam lies at most this far down the frame
FAR_LAG = 3         # frames between the fit that fixes the band and its first frame
FAR_SAMPLES = 15    # frames the band's background is estimated from,
FAR_SAMPLE_SECONDS = 0.4   # one every this many seconds before it starts


@dataclass(frozen=True)
class Band:
    """The far band in full-resolution rows: blobs whose centre lies above `seam` are the
    band's; its detector sees the rows [0, rows)."""

    seam: int
    rows: int


def far_band(coef: np.ndarray, mask_height: int, scale: float, height: int,
             min_pixels: int) -> Band | None:
    """The band of a frame `height` rows tall whose detection mask is `mask_height` rows
    (`scale` full-resolution pixels a mask pixel), from the scale field s = a + b u + c v
    (`coef`, mask pixels; sizes.fit_size); None where vehicles are not small at the top
    (a view from above, a junction) or the band would be too thin."""
    a, b, c = coef
    small = FAR_SIDE * np.sqrt(min_pixels)
    top = a + 0.5 * b
    if top >= small or c <= 0:
        return None
    v = min((small - top) / c, MAX_SHARE)    # s(0.5, v) = small
    seam = int(v * mask_height * scale)
    if seam < MIN_ROWS:
        return None
    return Band(seam, _rows(seam, scale, height, min_pixels))


def most_rows(mask_height: int, scale: float, height: int, min_pixels: int) -> int:
    """The most full-resolution rows `far_band` may give a band (its seam at MAX_SHARE of
    the frame), for the same arguments."""
    return _rows(int(MAX_SHARE * mask_height * scale), scale, height, min_pixels)


def _rows(seam: int, scale: float, height: int, min_pixels: int) -> int:
    """The rows a band's detector crops: the seam and SEAM_MARGIN vehicle sides below it."""
    margin = SEAM_MARGIN * FAR_SIDE * np.sqrt(min_pixels) * scale
    return min(height, int(np.ceil(seam + margin)))


def band_coef(coef: np.ndarray, scale: float, mask_height: int, rows: int) -> np.ndarray:
    """The scale field (`coef`, mask pixels of a frame `mask_height` rows tall) in the
    band's own pixels (full resolution, v over its `rows` rows), taken at the frame's
    centre column on every column: on a road plane seen by a camera without roll a
    vehicle's image size depends on its row alone, and the fit's slope across the frame
    (b) extrapolates to no size at all off the road, where the band would then take
    any speck for a vehicle."""
    a, b, c = coef
    return scale * np.array([a + 0.5 * b, 0.0, c * rows / (mask_height * scale)])


def seam_keep(boxes: np.ndarray, band_boxes: np.ndarray, band: Band
              ) -> tuple[np.ndarray, np.ndarray]:
    """Which blobs to keep of the first detector's (`boxes` (n, 4) x, y, w, h, frame
    pixels): those centred at or below the seam; and of the band's (`band_boxes`): those
    centred above it and not cut by the band's bottom edge."""
    keep = boxes[:, 1] + boxes[:, 3] / 2 >= band.seam
    bottom = band_boxes[:, 1] + band_boxes[:, 3]
    keep_band = (bottom - band_boxes[:, 3] / 2 < band.seam) & (bottom < band.rows - 1)
    return keep, keep_band
