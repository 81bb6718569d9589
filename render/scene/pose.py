"""Board poses: where a planar board (target or checkerboard) sits in front of the camera.

Frames: the OpenCV camera frame (x right, y down, z forward) is the world frame.
A board's local frame has its origin at the board centre, local x to image-right,
local y to image-down and local z pointing *away* from the camera (into the board),
so a fronto-parallel board at distance d is simply a translation by (ox, oy, d).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class Pose:
    """Board centre at (lateral_x_m, lateral_y_m, distance_m); tilts in degrees about local x then y."""

    distance_m: float
    lateral_x_m: float = 0.0
    lateral_y_m: float = 0.0
    tilt_x_deg: float = 0.0
    tilt_y_deg: float = 0.0
    roll_deg: float = 0.0

    @property
    def rotation(self) -> np.ndarray:
        """Local -> camera rotation: R = Ry(tilt_y) · Rx(tilt_x) · Rz(roll)."""
        ax, ay, az = np.radians([self.tilt_x_deg, self.tilt_y_deg, self.roll_deg])
        rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
        ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
        rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
        return ry @ rx @ rz

    @property
    def translation_m(self) -> np.ndarray:
        return np.array([self.lateral_x_m, self.lateral_y_m, self.distance_m], dtype=np.float64)

    @property
    def matrix(self) -> np.ndarray:
        """4×4 local -> camera transform."""
        m = np.eye(4)
        m[:3, :3] = self.rotation
        m[:3, 3] = self.translation_m
        return m

    def to_camera(self, points_local_m: np.ndarray) -> np.ndarray:
        """(N, 3) local board points -> camera frame."""
        p = np.asarray(points_local_m, dtype=np.float64).reshape(-1, 3)
        return p @ self.rotation.T + self.translation_m

    def to_dict(self) -> dict:
        d = asdict(self)
        d["R_cam_from_board"] = self.rotation.tolist()
        d["t_cam_from_board_m"] = self.translation_m.tolist()
        d["frame"] = "opencv camera frame (x right, y down, z forward); board local z points away from the camera"
        return d


#: A given rotation must be orthonormal (RᵀR = I) to this, with det +1; it is then replaced by the
#: nearest rotation (SVD), so the board stays rigid whatever rounding the numbers carry.
ROTATION_TOLERANCE = 1e-3


def nearest_rotation(r) -> np.ndarray:
    """The rotation closest to ``r`` (3×3) in the Frobenius norm (polar decomposition by SVD)."""
    u, _, vt = np.linalg.svd(np.asarray(r, dtype=np.float64))
    m = u @ vt
    if np.linalg.det(m) < 0:  # pragma: no cover - callers check det > 0 first
        u[:, -1] *= -1
        m = u @ vt
    return m


@dataclass(frozen=True)
class ExplicitPose(Pose):
    """A pose given as a rotation R (3×3, rows) and a translation t (m): X_cam = R X_board + t, the board
    frame as for ``Pose`` (x right, y down, z into the board).  ``distance_m`` and ``lateral_*_m`` are t;
    the tilt angles are unused (0).  ``rotation_rows`` must be a rotation (``nearest_rotation``)."""

    rotation_rows: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))

    @classmethod
    def from_rt(cls, r, t_m) -> "ExplicitPose":
        r = np.asarray(r, dtype=np.float64).reshape(3, 3)
        t = np.asarray(t_m, dtype=np.float64).reshape(3)
        return cls(distance_m=float(t[2]), lateral_x_m=float(t[0]), lateral_y_m=float(t[1]),
                   rotation_rows=tuple(tuple(float(v) for v in row) for row in r))

    @property
    def rotation(self) -> np.ndarray:
        return np.array(self.rotation_rows, dtype=np.float64)

    def moved_origin(self, offset_board_m) -> "ExplicitPose":
        """The same placement with the board frame's origin moved to ``offset_board_m`` (board frame):
        X_cam = R (X' + c) + t = R X' + (R c + t)."""
        return ExplicitPose.from_rt(self.rotation, self.rotation @ np.asarray(offset_board_m, float) + self.translation_m)

    def to_dict(self) -> dict:
        return {"explicit": True, "distance_m": self.distance_m, "lateral_x_m": self.lateral_x_m,
                "lateral_y_m": self.lateral_y_m, "R_cam_from_board": self.rotation.tolist(),
                "t_cam_from_board_m": self.translation_m.tolist(),
                "frame": "opencv camera frame (x right, y down, z forward); board local z points away from the "
                         "camera; X_cam = R_cam_from_board X_board + t_cam_from_board_m"}
