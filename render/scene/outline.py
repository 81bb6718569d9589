"""The exact image of a target's outline under lens distortion: a closed curve, not 4 corners.

A straight side of a square is a straight line only in the *undistorted* image; through the
distortion it bows (0.07 px on ``quick``, 0.3 px for the default lens at 0.6 m, 1.7 px for a
strong lens), so the chords between the distorted corners miss it.  ``OutlineCurve`` evaluates
the distorted curve at any parameter t in [0, 1) (the square's perimeter, side by side from the
top-left corner clockwise in the board frame, or the circle's angle 2πt), gives a dense polyline
whose chords stay within a stated distance of the curve, and signed distances of image points
to the curve (positive outside, on the bright board).

A ``polygon`` outline (``OutlineCurve.polygon``) is any planar polygon on the board, e.g. one square
of a board of squares anywhere on it: its straight sides, traversed in the given vertex order,
parameter t in [0, 1) with side floor(n t) from vertex floor(n t) to the next.

An ``ellipse`` outline (``OutlineCurve.ellipse``) is any conic of the shape catalogue on the board (a
circle, an ellipse, a ring's two edges anywhere on it): centre (cx, cy), semi-axes a, b, turned by
theta; parameter t is the angle 2πt from its turned +x axis towards +y.  ``OutlineCurve.of`` builds
either from an ``edgetruth.render.scene.shapes.Outline``.

With a moving camera the outline at time τ (seconds from mid-exposure) is the board point seen
from the camera moved by v·τ and rotated by ω·τ (``at_time``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.targets import TARGET_STANDOFF_M

POLYLINE_STEP_PX = 2.0  # largest spacing of the dense polyline along the distorted curve
CHORD_TOLERANCE_PX = 1e-3  # circles: the spacing keeps chords within this of the curve (step² / (8 r))


def rotation_about(omega_rad_s: np.ndarray, tau_s: float) -> np.ndarray:
    """Rotation matrix of the angular velocity ``omega_rad_s`` over ``tau_s`` (Rodrigues)."""
    w = np.asarray(omega_rad_s, float) * tau_s
    a = float(np.linalg.norm(w))
    if a == 0:
        return np.eye(3)
    k = w / a
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * kx + (1.0 - math.cos(a)) * kx @ kx


def camera_points_at(camera: Camera, points_mid_m: np.ndarray, tau_s: float) -> np.ndarray:
    """Camera-frame coordinates at time τ of points given in the mid-exposure camera frame: the
    camera sits at v·τ, rotated by ω·τ (as the sensor plugin moves its rays)."""
    r = rotation_about(np.radians(camera.angular_velocity_deg_s), tau_s)
    c = np.asarray(camera.velocity_m_s, float) * tau_s
    return (np.asarray(points_mid_m, float) - c) @ r  # R^T (p - c), row vectors


@dataclass(frozen=True)
class OutlineCurve:
    """The outline of a square (side) or circle (diameter) ``size_m`` at ``pose``, seen by ``camera``;
    or (``shape = "polygon"``) the polygon of ``vertices`` (board frame, (n, 3) as nested tuples)."""

    camera: Camera
    pose: Pose
    shape: str
    size_m: float
    standoff_m: float = TARGET_STANDOFF_M
    vertices: tuple | None = None
    #: ``shape = "ellipse"``: (cx, cy, a, b, theta_rad) in the board frame (semi-axes a, b)
    conic: tuple | None = None
    #: a curled board (``render.scene.bend.BoardBend``): every point lifted by its height; None: flat
    bend: object = None

    @classmethod
    def polygon(cls, camera: Camera, pose: Pose, vertices_local, bend=None) -> "OutlineCurve":
        """The outline of the polygon with ``vertices_local`` ((n, 3) board frame, z included), on a board
        curled by ``bend`` (its sides then follow the surface: curves in space)."""
        v = np.asarray(vertices_local, dtype=np.float64).reshape(-1, 3)
        return cls(camera, pose, "polygon", 0.0, standoff_m=float(-v[0, 2]),
                   vertices=tuple(tuple(float(c) for c in row) for row in v), bend=bend)

    @classmethod
    def ellipse(cls, camera: Camera, pose: Pose, conic, standoff_m: float = TARGET_STANDOFF_M) -> "OutlineCurve":
        """The outline of the board ellipse ``conic`` = (cx, cy, a, b, theta_rad) at z = -standoff_m."""
        return cls(camera, pose, "ellipse", 2.0 * float(max(conic[2], conic[3])), standoff_m=float(standoff_m),
                   conic=tuple(float(c) for c in conic))

    @classmethod
    def of(cls, camera: Camera, pose: Pose, outline, standoff_m: float) -> "OutlineCurve":
        """The curve of a catalogue ``Outline`` (``edgetruth.render.scene.shapes``) at z = -standoff_m (a
        ``SpaceOutline``'s 3-D corners as they are)."""
        if outline.kind == "ellipse":
            return cls.ellipse(camera, pose, outline.conic, standoff_m)
        v = np.asarray(outline.vertices, float)
        if v.shape[1] == 3:  # a 3-D polygon (a box's silhouette): its corners at their own heights
            return cls.polygon(camera, pose, v)
        return cls.polygon(camera, pose, np.column_stack([v, np.full(len(v), -float(standoff_m))]))

    def _pieces(self) -> int:
        return {"square": 4, "polygon": len(self.vertices or ())}.get(self.shape, 1)

    def local(self, t) -> np.ndarray:
        """Board-frame points at curve parameters t (N,) -> (N, 3)."""
        p = self._flat_local(t)
        return p if self.bend is None else self.bend.lift(p)

    def _flat_local(self, t) -> np.ndarray:
        t = np.mod(np.asarray(t, float), 1.0)
        h = self.size_m / 2.0
        z = np.full_like(t, -self.standoff_m)
        if self.shape == "polygon":
            v = np.asarray(self.vertices, dtype=np.float64)
            n = len(v)
            k = np.minimum((n * t).astype(int), n - 1)
            s = n * t - k
            nxt = np.roll(v, -1, axis=0)
            return v[k] + (nxt[k] - v[k]) * s[:, None]
        if self.shape == "ellipse":
            cx, cy, a, b, th = self.conic
            ang = 2.0 * np.pi * t
            c, s_ = math.cos(th), math.sin(th)
            u, w = a * np.cos(ang), b * np.sin(ang)
            return np.column_stack([cx + c * u - s_ * w, cy + s_ * u + c * w, z])
        if self.shape == "square":
            corners = np.array([[-h, -h], [h, -h], [h, h], [-h, h], [-h, -h]])  # TL, TR, BR, BL (board frame)
            k = np.minimum((4.0 * t).astype(int), 3)
            s = 4.0 * t - k
            xy = corners[k] + (corners[k + 1] - corners[k]) * s[:, None]
            return np.column_stack([xy, z])
        a = 2.0 * np.pi * t
        return np.column_stack([h * np.cos(a), h * np.sin(a), z])

    def points(self, t, distorted: bool = True, tau_s: float = 0.0) -> np.ndarray:
        """(N, 2) OpenCV pixel positions of the outline at parameters t (at time τ from mid-exposure)."""
        p = self.pose.to_camera(self.local(t))
        if tau_s:
            p = camera_points_at(self.camera, p, tau_s)
        return self.camera.project(p, distorted=distorted)

    def default_step_px(self) -> float:
        """``POLYLINE_STEP_PX``, finer for circles: chords within ``CHORD_TOLERANCE_PX`` of the curve."""
        if self.shape in ("square", "polygon"):
            return POLYLINE_STEP_PX
        ring = self.points(np.linspace(0.0, 1.0, 64, endpoint=False))
        r_px = 0.5 * float(np.min(np.ptp(ring, axis=0)))
        # 0.8: the ellipse of a tilted circle curves more than its mean radius says
        return min(POLYLINE_STEP_PX, 0.8 * math.sqrt(8.0 * CHORD_TOLERANCE_PX * max(r_px, 1.0)))

    def parameters(self, step_px: float | None = None) -> np.ndarray:
        """Curve parameters spaced at most ``step_px`` apart in the image (the corners included)."""
        step_px = step_px or self.default_step_px()
        pieces = self._pieces()
        out = []
        for k in range(pieces):
            t0, t1 = k / pieces, (k + 1) / pieces
            probe = self.points(np.linspace(t0, t1, 65)[:-1] if pieces == 1 else np.linspace(t0, t1, 65))
            length = float(np.sum(np.linalg.norm(np.diff(probe, axis=0), axis=1)))
            if pieces == 1:
                length += float(np.linalg.norm(probe[0] - probe[-1]))
            n = max(8, int(math.ceil(1.1 * length / step_px)))  # 1.1: perspective makes the spacing uneven
            out.append(t0 + (t1 - t0) * np.arange(n) / n)
        return np.concatenate(out)

    def polyline(self, step_px: float | None = None, distorted: bool = True) -> np.ndarray:
        """Dense closed polyline (N, 2) on the curve (first point not repeated)."""
        return self.points(self.parameters(step_px), distorted)

    def chord_error_px(self, step_px: float | None = None) -> float:
        """Largest distance between a chord of ``polyline`` and the curve (midpoint check)."""
        t = self.parameters(step_px)
        t_next = np.r_[t[1:], 1.0]
        a, b = self.points(t), self.points(t_next)
        mid = self.points(0.5 * (t + t_next))
        d = b - a
        n = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
        return float(np.max(np.abs(((mid - a) * n).sum(axis=1))))

    def signed_distance(self, x, y, step_px: float = 0.25, exact: bool = False) -> np.ndarray:
        """Signed distance (px) of image points to the distorted curve: > 0 outside (the bright board).

        Nearest point on a polyline of ``step_px`` spacing (chord error ~ step² κ / 8: below 1e-4 px for
        radii of curvature above ~80 px, 2e-4 px for a 40 px circle).  ``exact``: the nearest point is then
        refined on the curve itself (golden-section search of the curve parameter between the nearest
        vertex's neighbours; to ~1e-9 px), the sign kept from the polyline."""
        from edgetruth.render.edge_truth import closed_polyline_signed_distance

        t = self.parameters(step_px)
        poly = self.points(t)
        sd = closed_polyline_signed_distance(poly, x, y)
        if not exact:
            return sd
        from scipy.spatial import cKDTree

        q = np.column_stack([np.ravel(x), np.ravel(y)]).astype(float)
        if not len(q):
            return sd
        _, k = cKDTree(poly).query(q)
        tt = np.r_[t[-1] - 1.0, t, t[0] + 1.0]  # unwrapped neighbours
        lo, hi = tt[k], tt[k + 2]

        def f(tp):
            return np.linalg.norm(self.points(tp) - q, axis=1)

        g = 0.5 * (math.sqrt(5.0) - 1.0)
        a, b = lo.copy(), hi.copy()
        for _ in range(60):  # the bracket shrinks by 0.618 per step: ~3e-13 of it after 60
            c, d = b - g * (b - a), a + g * (b - a)
            left = f(c) < f(d)
            b = np.where(left, d, b)
            a = np.where(left, a, c)
        dist = f(0.5 * (a + b))
        return (np.sign(sd).ravel() * dist).reshape(np.shape(sd))
