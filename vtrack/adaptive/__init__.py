"""The seed papers' adaptive and fuzzy filter kinds, on top of the estimation core.

ankf1, ankf2 (seed 000: innovation-based adaptive estimation, adaptive fading), fuzzy-r,
fuzzy-q (seed 003: Mamdani-adapted R or Q) and siim-ekf (seed 004: the SIIM fuzzy EKF). Each
is the core EKF with its Q and R supplied through the EKF's hooks; importing this package
registers the kinds in the core's registry (vtrack.estimation.registry).
"""

from vtrack.adaptive import ankf, fuzzy, siim  # noqa: F401  (register their kinds)
