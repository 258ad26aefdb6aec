"""Simulation: synthetic traffic video with ground truth; seed scenarios."""
