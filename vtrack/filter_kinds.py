"""Every filter kind of vtrack, built by name: the core's (vtrack.estimation: kf, ekf, iekf,
ukf, ckf, iplf, srukf, crukf) and the seed papers' adaptive and fuzzy kinds (vtrack.adaptive:
ankf1, ankf2, fuzzy-r, fuzzy-q, siim-ekf), which register themselves in the core's registry
when imported here. Applications (`vtrack filter`, the tracker, the experiments) build their
filters with this `make_filter`.
"""

import vtrack.adaptive  # noqa: F401  (registers the adaptive and fuzzy kinds)
from vtrack.estimation.registry import FILTER_KINDS, make_filter

__all__ = ["FILTER_KINDS", "make_filter"]
