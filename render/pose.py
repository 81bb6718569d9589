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
