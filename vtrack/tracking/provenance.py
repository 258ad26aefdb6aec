"""Measurement provenance: which detections are whole vehicles.

The fused detector (vision/fusion.py) says where each box came from: MOTION (a blob of
background subtraction), APPEARANCE or BOTH (a box the appearance model drew). A box the
appearance model drew is a whole vehicle; a motion-only blob may be a part of one (an
occluder cut it), a merge of several, or carry a shadow. So each role of the tracker treats
a whole box as whole and keeps its blob heuristics for motion-only measurements:

- fragments (fragments.py): a whole box is never a piece to join with others;
- shared detections (associator.resolve_shared): a whole box holding several tracks'
  centres is one vehicle, not a merged blob: it is not consumed; its tracks are duplicates
  only where their boxes are alike (IoU, not the overlap of the smaller: a vehicle hidden
  behind another), and a duplicate on it is deleted only after `whole_duplicate_seconds`
  (a vehicle behind another whose own box is missing for a frame keeps its track);
- initiation (lifecycle.Initiator): a whole box that no track took starts a track even with
  its centre in a confirmed track's box (a vehicle behind another), unless it is that
  track's box (IoU >= `blob_fit_iou`);
- association (associator.py): a whole box that no border cuts measures the vehicle's
  centre, and its sides' squared Mahalanobis distance from the track's size adds to the
  assignment's cost (box_size.d2; a side the border cuts counts only where it is larger
  than the track's): a vehicle entering where another leaves is not the one leaving;
  whole boxes are assigned before blobs (a blob's cost has no size term: a piece nearer
  the predicted centre would otherwise win the track from its vehicle's whole box);
- sizes (sizes.py): a whole box is never a partial view behind a static occluder, and a
  smaller whole box restarts the size at once (no `size_shrink_seconds` wait), unless it
  lies within CUT_SIGMAS of its detection sigma of the image border (`near_border`: a
  drawn box's edges scatter around the border, so it may be cut by it; the size gate then
  holds the size as for a blob);
- confirmation (lifecycle.Confirmer): a track a whole box measured is a vehicle by its
  looks and needs no motion (`LifeColumns.seen`).

Without provenance (a motion detector: `seen` None or all false) every detection is a blob
and every role takes exactly its blob path.
"""

from __future__ import annotations

import numpy as np

from vtrack.tracking.config import TrackerConfig
from vtrack.tracking.measurements import border_cut, detection_sigma

CUT_SIGMAS = 2.0   # a whole box's edge this many detection sigmas from the border may be cut


def near_border(cfg: TrackerConfig, boxes: np.ndarray, width: int, height: int
                ) -> np.ndarray:
    """(K,) boxes (K, 4) with an edge within CUT_SIGMAS of their detection sigma of the
    image border: a drawn box's edges scatter around the border, so such a box may be cut
    by it even where its edge is not on it."""
    tol = CUT_SIGMAS * detection_sigma(cfg, np.sqrt(boxes[:, 2] * boxes[:, 3]))
    return border_cut(boxes, width, height, tol).any(axis=(1, 2))


def whole_boxes(seen: np.ndarray | None, n: int) -> np.ndarray:
    """(n,) bool: the detections the appearance model drew (`Detections.seen`; None: none)."""
    if seen is None:
        return np.zeros(n, dtype=bool)
    whole = np.asarray(seen, dtype=bool).reshape(-1)
    if len(whole) != n:
        raise ValueError(f"seen has {len(whole)} entries for {n} detections")
    return whole
