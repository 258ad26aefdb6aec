"""GPS-aided strapdown inertial navigation (seed 001 section 4), on top of the estimation core:
rotations (so3), the mechanisation and its linear error model (strapdown), and the
closed-loop error-state Kalman filter built on the core's kalman.kf_predict / kf_update
(error_state_filter)."""
