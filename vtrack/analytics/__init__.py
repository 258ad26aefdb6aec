"""Traffic analytics on confirmed tracks: counting lines, zones, calibration, time bins."""
