"""Stage 1: pixel-level Canny candidates and their gradient direction.

Every method refines the *same* candidates (the study's unified framework).
The image is smoothed with a Gaussian of ``sigma_px``; the gradient (Sobel,
scaled to gray levels per pixel) of the smoothed image gives the unit normal
n = grad / |grad|, pointing from the dark side to the bright side.  OpenCV's
Canny runs on that gradient (L2 magnitude), so candidates and normals come
from one field.

Candidates are dropped when any refinement would read outside the image:
all 11 normal-profile samples p + t n, t = -5..5, must lie inside the hull of
pixel centres, and p must be at least ``MASK_MARGIN_PX`` pixels from the
border (room for 7x7 moment masks).  A constant image has no candidates.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from edgetruth.errors import InputError
from edgetruth.locate.image_input import as_float_image

#: Half-length of the normal profile every method may read (t = -5..5).
PROFILE_HALF = 5
#: Square margin kept around every candidate (7x7 masks need 3 px).
MASK_MARGIN_PX = 3


@dataclass(frozen=True)
class Candidates:
    """Pixel-level edge candidates of one image (OpenCV coordinates), shared by every method.

    A candidate is a Canny edge pixel whose 11-sample normal profile (t = -5..5 px) and 7x7 neighbourhood
    lie inside the image.

    Attributes
    ----------
    x, y : numpy.ndarray
        float64 (N,): integer-valued pixel centres (x = column, y = row).
    nx, ny : numpy.ndarray
        float64 (N,): the unit gradient direction, dark to bright.
    magnitude : numpy.ndarray
        float64 (N,): smoothed gradient magnitude, gray levels per px.
    shape : tuple of int
        (H, W) of the image.
    sigma_px : float
        The Gaussian smoothing used, px.
    grad_x, grad_y : numpy.ndarray
        float64 (H, W): the smoothed gradient fields the normals came from.
    smoothed : numpy.ndarray
        float64 (H, W): the Gaussian-smoothed image.
    thresholds : tuple of float
        Canny's (low, high) hysteresis thresholds used, gray levels per px.
    """

    x: np.ndarray
    y: np.ndarray
    nx: np.ndarray
    ny: np.ndarray
    magnitude: np.ndarray
    shape: tuple[int, int]
    sigma_px: float
    grad_x: np.ndarray = field(repr=False)
    grad_y: np.ndarray = field(repr=False)
    smoothed: np.ndarray = field(repr=False)
    thresholds: tuple[float, float] = (0.0, 0.0)

    def __len__(self) -> int:
        return int(self.x.shape[0])

    def subset(self, mask_or_index) -> "Candidates":
        """The candidates selected by a boolean mask or an index array (the image fields are shared).

        Parameters
        ----------
        mask_or_index : numpy.ndarray
            (N,) bool, or integer indices.

        Returns
        -------
        Candidates
            The selected candidates, in the order given.
        """
        sel = np.asarray(mask_or_index)
        return Candidates(
            self.x[sel], self.y[sel], self.nx[sel], self.ny[sel], self.magnitude[sel],
            self.shape, self.sigma_px, self.grad_x, self.grad_y, self.smoothed, self.thresholds,
        )


def smoothed_gradient(image: np.ndarray, sigma_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gaussian-smoothed image and its Sobel gradient in gray levels per pixel."""
    smooth = cv2.GaussianBlur(image, (0, 0), sigmaX=sigma_px, sigmaY=sigma_px, borderType=cv2.BORDER_REFLECT)
    gx = cv2.Sobel(smooth, cv2.CV_64F, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT) / 8.0
    gy = cv2.Sobel(smooth, cv2.CV_64F, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT) / 8.0
    return smooth, gx, gy


def _default_thresholds(mag: np.ndarray) -> tuple[float, float]:
    """Hysteresis thresholds from the gradient statistics of the image.

    high = max(0.3 * max|g|, 6 * sigma_g) and low = high / 3, where sigma_g is
    the noise scale of the gradient estimated from the median magnitude
    (Rayleigh: median = 1.1774 sigma) -- most pixels of a measurement image are
    off-edge, so the median is a noise statistic.
    """
    peak = float(mag.max())
    sigma_g = float(np.median(mag)) / 1.1774
    high = max(0.3 * peak, 6.0 * sigma_g)
    return high / 3.0, high


def window_inside(x, y, nx, ny, shape, half: int = PROFILE_HALF, margin_px: int = MASK_MARGIN_PX) -> np.ndarray:
    """True where the profile p + t n (|t| <= half) and the square margin stay inside the image."""
    h, w = shape
    ex = half * np.abs(nx)
    ey = half * np.abs(ny)
    m = float(margin_px)
    return (
        (x - np.maximum(ex, m) >= 0) & (x + np.maximum(ex, m) <= w - 1)
        & (y - np.maximum(ey, m) >= 0) & (y + np.maximum(ey, m) <= h - 1)
    )


def candidates(
    image,
    sigma_px: float = 1.0,
    low: float | None = None,
    high: float | None = None,
    name: str = "image",
) -> Candidates:
    """Stage 1: Canny candidates of ``image`` with unit normals from the smoothed gradient.

    Canny (OpenCV, L2 gradient) on the image smoothed by a Gaussian of ``sigma_px``; the normal is the
    smoothed gradient's direction. A candidate is dropped when any method would read outside the image.

    Parameters
    ----------
    image : numpy.ndarray
        A 2-D image (H, W): uint8, uint16 or float gray levels.
    sigma_px : float, optional
        The Gaussian smoothing, px (0.3-10; default 1).
    low, high : float, optional
        Hysteresis thresholds on the smoothed gradient magnitude, gray levels per px. Default:
        high = max(0.3 max|g|, 6 sigma_g) with sigma_g the gradient's noise scale from its median, low = high / 3.
    name : str, optional
        What error messages call the image.

    Returns
    -------
    Candidates
        The candidates, in raster order.
    """
    img = as_float_image(image, name)
    try:
        sigma_px = float(sigma_px)
        low = None if low is None else float(low)
        high = None if high is None else float(high)
    except (TypeError, ValueError) as exc:
        raise InputError(f"sigma_px={sigma_px!r}, low={low!r}, high={high!r}: must be numbers") from exc
    if not (np.isfinite(sigma_px) and 0.3 <= sigma_px <= 10.0):
        raise InputError(f"sigma_px={sigma_px}: must be a number in [0.3, 10] pixels")
    smooth, gx, gy = smoothed_gradient(img, sigma_px)
    mag = np.hypot(gx, gy)
    empty = np.zeros(0)
    peak = float(mag.max())
    if not peak > 0.0 or peak <= 1e-12 * max(1.0, float(np.abs(img).max())):
        return Candidates(empty, empty, empty, empty, empty, img.shape, sigma_px, gx, gy, smooth)
    lo_d, hi_d = _default_thresholds(mag)
    lo = lo_d if low is None else float(low)
    hi = hi_d if high is None else float(high)
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo <= hi):
        raise InputError(f"thresholds low={low}, high={high}: need 0 <= low <= high (gray levels per pixel)")
    # Canny's gradient overload takes int16 derivatives: scale the field so the
    # peak uses most of the int16 range, and the thresholds with it.
    scale = 16000.0 / max(float(np.abs(gx).max()), float(np.abs(gy).max()))
    dx = np.round(gx * scale).astype(np.int16)
    dy = np.round(gy * scale).astype(np.int16)
    edges = cv2.Canny(dx, dy, lo * scale, hi * scale, L2gradient=True)
    ys, xs = np.nonzero(edges)
    xs = xs.astype(np.float64)
    ys = ys.astype(np.float64)
    g = mag[ys.astype(np.intp), xs.astype(np.intp)]
    ok = g > 0
    xs, ys, g = xs[ok], ys[ok], g[ok]
    nx = gx[ys.astype(np.intp), xs.astype(np.intp)] / g
    ny = gy[ys.astype(np.intp), xs.astype(np.intp)] / g
    keep = window_inside(xs, ys, nx, ny, img.shape)
    return Candidates(
        xs[keep], ys[keep], nx[keep], ny[keep], g[keep], img.shape, float(sigma_px), gx, gy, smooth, (lo, hi)
    )
