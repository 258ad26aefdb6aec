"""Adaptive filter kinds (ANKF1/ANKF2 of seed 000, fuzzy-R/Q of seed 003, SIIM EKF of seed 004).

Registered into vtrack.estimation.filters.FILTER_KINDS on import.
"""
