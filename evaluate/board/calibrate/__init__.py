"""Zhang calibration of a row's corners, leave-one-image-out reprojection and side lengths (``zhang``)."""
