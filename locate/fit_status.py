"""Per-point status codes shared by every fitting kernel (extras column ``status``)."""
OK = 0  # converged, parameters inside their valid range
NOT_CONVERGED = 1  # iteration limit or no decrease possible
NO_CONTRAST = 2  # flat window: nothing to fit
OUT_OF_WINDOW = 3  # converged, but the position or width left the model's valid range
