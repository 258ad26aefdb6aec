"""The MOG2 vehicle detector (`detect`) and its stages, and frame annotation (`annotate`).
Video input/output is vtrack.io. Import the submodules directly; this package imports
nothing heavy."""
