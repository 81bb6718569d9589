"""Undistortion of target images with the *calibrated* model (as a real user would).

The undistorted image keeps the calibrated intrinsic matrix (``newCameraMatrix = K``),
so ranging uses the calibrated fx on it directly, and points located on it are
ideal-pinhole pixel coordinates in the OpenCV convention.

Resampling and its interpolation
--------------------------------
Undistortion resamples the image: each output pixel centre is mapped through
the forward distortion model to a (non-integer) source position and the source
is interpolated there (``cv2.initUndistortRectifyMap`` + ``cv2.remap``).  The
default is **bilinear (``cv2.INTER_LINEAR``)**, chosen by measurement, not taste:

* bilinear is a 2x2, non-negative kernel: it cannot overshoot, so a monotone edge
  profile stays monotone - the shape every fitted edge model (ERF, arctan,
  sigmoid, moments) assumes.  Its cost is a mild, position-dependent low-pass
  (up to a [1/2, 1/2] kernel at half-pixel source offsets), symmetric, so it
  widens an edge without moving it;
* bicubic (Keys, a = -0.75) and Lanczos-4 are sharper but ring: on a sharp edge
  (in focus, blur < 1 px, as in most of these renders) the overshoot of a few %
  of the contrast lies *inside* the 5-11 point fitting windows and biases the
  ERF fits.  Measured on the ``quick`` renders with the true model (RMS of the
  target-size error l_hat - l_true, px, 5 images): dynamic_erf_4p 0.055 (linear)
  vs 0.135 (cubic) vs 0.124 (Lanczos-4); erf4p_fixed11 0.051 / 0.106 / 0.120;
  Canny-Devernay 0.036 / 0.020 / 0.025; SER-CIS 0.015 / 0.029 / 0.017.  The worst
  single case, the in-focus gray square (T3), went from +0.045 px (linear) to
  +0.280 px (cubic) for dynamic_erf_4p.

Edges are then located on the undistorted image, as in the seed study.  The border
(where the undistorted view maps outside the sensor) is filled by replicating the
nearest valid pixel, so it creates no artificial edge; ``valid_mask`` says where
the output is genuine image content.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from edgetruth.evaluate.calibration import undistort_px


INTERPOLATIONS = {"linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC, "lanczos4": cv2.INTER_LANCZOS4}
DEFAULT_INTERPOLATION = "linear"


@dataclass
class Undistorter:
    """Undistorts images of one size with one (K, dist) model; maps are built once."""

    K: np.ndarray
    dist: np.ndarray
    size: tuple[int, int]  # (width, height)
    interpolation: str = DEFAULT_INTERPOLATION
    _maps: tuple | None = field(default=None, repr=False)

    def maps(self):
        if self._maps is None:
            K = np.asarray(self.K, np.float64)
            self._maps = cv2.initUndistortRectifyMap(K, np.asarray(self.dist, np.float64), None, K,
                                                     tuple(self.size), cv2.CV_32FC1)
        return self._maps

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """The undistorted image (float64), same size and intrinsic matrix K."""
        mx, my = self.maps()
        img = np.asarray(image, dtype=np.float32)
        out = cv2.remap(img, mx, my, INTERPOLATIONS[self.interpolation], borderMode=cv2.BORDER_REPLICATE)
        return out.astype(np.float64)

    def valid_mask(self, margin_px: float = 2.0) -> np.ndarray:
        """True where the output pixel's source lies inside the sensor (``margin_px`` inside)."""
        mx, my = self.maps()
        w, h = self.size
        return (mx >= margin_px) & (my >= margin_px) & (mx <= w - 1 - margin_px) & (my <= h - 1 - margin_px)

    def undistort_points(self, pts_px: np.ndarray) -> np.ndarray:
        """Distorted pixel coordinates (N, 2) -> undistorted pixel coordinates with the same K."""
        return undistort_px(np.asarray(pts_px, np.float64).reshape(-1, 2), self.K, self.dist)


def from_calibration(cal, interpolation: str = DEFAULT_INTERPOLATION) -> Undistorter:
    """An ``Undistorter`` for a ``edgetruth.evaluate.calibration.Calibration``."""
    return Undistorter(cal.K, cal.dist, tuple(cal.image_size), interpolation)


def from_truth(gt: dict, interpolation: str = DEFAULT_INTERPOLATION) -> Undistorter:
    """An ``Undistorter`` with the TRUE model of a ground-truth dict (for checking only)."""
    cam = gt["camera"]
    return Undistorter(np.asarray(cam["K"]), np.asarray(cam["dist_coeffs_opencv"]),
                       (int(cam["width_px"]), int(cam["height_px"])), interpolation)
