"""Visualisation back-ends (rerun). Nothing here is imported unless asked for."""
