"""The shared estimation core: models, Kalman and sigma-point filters, bounds.

Pure NumPy/SciPy. It never prints, never touches files and knows nothing of video or rerun.
"""
