"""Evaluation: MOT metrics on MOTChallenge files."""
