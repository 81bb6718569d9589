"""The pinhole image of a circle on a plane: a conic whose centre is not the image of the circle's centre.

A board point (X, Y) on the plane z = z0 of the board frame images (pinhole, homogeneous) at
H (X, Y, 1)ᵀ with the plane's homography H = K [r1  r2  z0 r3 + t] (r_k the columns of R, X_cam = R X + t).
A circle of centre (a, b) and radius ρ is the conic

    C = [[1, 0, −a], [0, 1, −b], [−a, −b, a² + b² − ρ²]],   (X, Y, 1) C (X, Y, 1)ᵀ = 0,

and its image the conic C' = H⁻ᵀ C H⁻¹ (``image_conic``).  A conic's centre is the pole of the line at
infinity, c' ~ C'⁻¹ (0, 0, 1)ᵀ = H C⁻¹ Hᵀ (0, 0, 1)ᵀ.  Hᵀ (0, 0, 1)ᵀ is H's third row, the board line whose
points have camera depth 0 (the vanishing line pulled back to the board): l = (R₂₀, R₂₁, Z_c − R₂₀ a − R₂₁ b)
with Z_c the depth of the circle's centre.  Its pole for the circle is, in closed form,

    c + δ,   δ = −(ρ² / Z_c) (R₂₀, R₂₁)                                     (``conic_centre_board``)

so the image ellipse's centre is the *pinhole image of the board point c + δ*: the circle's centre moved
ρ² / Z_c times the depth's gradient along the board, away from the deeper side (towards the camera).  Its
length ρ² sin θ / Z_c (θ the board's tilt) is exact, not a first-order term; the image offset from the
image of c follows by projecting both (Heikkilä 2000, IEEE PAMI 22(10), writes the same centre in image
terms).  Lens distortion comes after the pinhole: the distorted outline is no conic, and the truth gives the
pinhole conic's centre (``undistorted`` pixels) beside the image of the centre both ways.

Pure numpy, vectorised over circles; no camera object (K, R, t as arrays) so evaluate's calibration uses the
same formulas with its own estimates.
"""
from __future__ import annotations

import numpy as np


def circle_conics(centres_xy: np.ndarray, radius: float | np.ndarray) -> np.ndarray:
    """(n, 3, 3) the conic matrices of circles of ``centres_xy`` (n, 2) and ``radius`` (scalar or (n,))."""
    c = np.asarray(centres_xy, np.float64).reshape(-1, 2)
    r = np.broadcast_to(np.asarray(radius, np.float64), (len(c),))
    out = np.zeros((len(c), 3, 3))
    out[:, 0, 0] = out[:, 1, 1] = 1.0
    out[:, 0, 2] = out[:, 2, 0] = -c[:, 0]
    out[:, 1, 2] = out[:, 2, 1] = -c[:, 1]
    out[:, 2, 2] = (c ** 2).sum(axis=1) - r ** 2
    return out


def plane_homography(K: np.ndarray, R: np.ndarray, t: np.ndarray, z_m: float = 0.0) -> np.ndarray:
    """(3, 3) H: board (X, Y, 1) on the plane z = ``z_m`` of the board frame -> undistorted pixels
    (homogeneous), X_cam = R X + t."""
    R = np.asarray(R, np.float64)
    m = np.column_stack([R[:, 0], R[:, 1], z_m * R[:, 2] + np.asarray(t, np.float64).ravel()])
    return np.asarray(K, np.float64) @ m


def image_conic(H: np.ndarray, conics: np.ndarray) -> np.ndarray:
    """(n, 3, 3) the image conics C' = H⁻ᵀ C H⁻¹ of board conics ``conics`` (n, 3, 3), scaled to unit norm."""
    Hi = np.linalg.inv(np.asarray(H, np.float64))
    q = Hi.T[None] @ np.asarray(conics, np.float64) @ Hi[None]
    return q / np.linalg.norm(q, axis=(1, 2), keepdims=True)


def conic_centre(conics: np.ndarray) -> np.ndarray:
    """(n, 2) the centres of conics (n, 3, 3) [[a, b, d], [b, c, e], [d, e, f]]: the solution of
    [[a, b], [b, c]] x = −(d, e)."""
    q = np.asarray(conics, np.float64).reshape(-1, 3, 3)
    return np.linalg.solve(q[:, :2, :2], -q[:, :2, 2:3])[..., 0]


def conic_centre_board(R: np.ndarray, t: np.ndarray, centres_xy: np.ndarray, radius: float | np.ndarray,
                       z_m: float = 0.0) -> np.ndarray:
    """(n, 3) the board points (z = ``z_m``) whose pinhole images are the centres of the circles' image
    ellipses: c − (ρ² / Z_c) (R₂₀, R₂₁) (module docstring)."""
    R = np.asarray(R, np.float64)
    c = np.asarray(centres_xy, np.float64).reshape(-1, 2)
    r = np.broadcast_to(np.asarray(radius, np.float64), (len(c),))
    local = np.column_stack([c, np.full(len(c), float(z_m))])
    zc = local @ R[2] + float(np.asarray(t, np.float64).ravel()[2])
    shift = -(r ** 2 / zc)[:, None] * R[2, :2][None]
    return np.column_stack([c + shift, local[:, 2]])


def pinhole_px(K: np.ndarray, R: np.ndarray, t: np.ndarray, points_local: np.ndarray) -> np.ndarray:
    """(n, 2) undistorted pixels of board points (n, 3): K (R X + t), dehomogenised."""
    p = np.asarray(points_local, np.float64) @ np.asarray(R, np.float64).T + np.asarray(t, np.float64).ravel()
    q = p @ np.asarray(K, np.float64).T
    return q[:, :2] / q[:, 2:3]


def conic_centre_px(K, R, t, centres_xy, radius, z_m: float = 0.0) -> np.ndarray:
    """(n, 2) undistorted pixels of the circles' image-ellipse centres, in closed form (``conic_centre_board``)."""
    return pinhole_px(K, R, t, conic_centre_board(R, t, centres_xy, radius, z_m))


def centre_bias_px(K, R, t, centres_xy, radius, z_m: float = 0.0) -> np.ndarray:
    """(n, 2) the image ellipse's centre minus the image of the circle's centre (undistorted pixels): the
    perspective bias of a centre taken from the ellipse."""
    c = np.asarray(centres_xy, np.float64).reshape(-1, 2)
    local = np.column_stack([c, np.full(len(c), float(z_m))])
    return conic_centre_px(K, R, t, c, radius, z_m) - pinhole_px(K, R, t, local)
