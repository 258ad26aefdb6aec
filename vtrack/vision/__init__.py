"""Video input/output (`video`), the MOG2 vehicle detector (`detect`) and frame annotation
(`annotate`). Import the submodules directly; this package imports nothing heavy."""
