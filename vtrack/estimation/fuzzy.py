"""Fuzzy-adaptive filter kinds (fuzzy-r, fuzzy-q of seed 003; siim-ekf of seed 004)."""
