"""The camera: intrinsics, thin-lens aperture and Brown–Conrady distortion from a spec.

All image coordinates are OpenCV's (see ``edgetruth.conventions``); points in
camera space are in the OpenCV camera frame (x right, y down, z forward), metres.
The renderer uses the same frame as its world frame, so a pose is simply where
the board sits in front of the camera.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from edgetruth.conventions import focal_length_px, principal_point_centred
from edgetruth.errors import InputError, require
from edgetruth.paths import ASSETS_DIR
from render.distortion import distort_normalized, undistort_normalized
from render.spec import load_toml

DEFAULT_CAMERA = "default"


@dataclass(frozen=True)
class Camera:
    """A thin-lens camera with square pixels and a centred optical axis."""

    width_px: int = 1280
    height_px: int = 1024
    pitch_um: float = 4.8
    focal_length_mm: float = 8.0
    f_number: float = 4.0
    focus_distance_m: float = 1.5
    #: OpenCV order (k1, k2, p1, p2, k3).
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    name: str = field(default="custom", compare=False)

    def __post_init__(self) -> None:
        require(self.width_px > 0 and self.height_px > 0, f"camera {self.name}: resolution must be positive")
        require(self.pitch_um > 0 and self.focal_length_mm > 0, f"camera {self.name}: pitch and focal length must be positive")
        require(self.f_number >= 0, f"camera {self.name}: f_number must be >= 0 (0 = pinhole)")
        require(self.focus_distance_m > 0, f"camera {self.name}: focus_distance_m must be positive")
        require(len(self.distortion) == 5, f"camera {self.name}: distortion needs 5 coefficients (k1, k2, p1, p2, k3)")

    # --- derived quantities -------------------------------------------------
    @property
    def pitch_m(self) -> float:
        return self.pitch_um * 1e-6

    @property
    def focal_length_m(self) -> float:
        return self.focal_length_mm * 1e-3

    @property
    def fx_px(self) -> float:
        return focal_length_px(self.focal_length_m, self.pitch_m)

    @property
    def principal_point_px(self) -> tuple[float, float]:
        return principal_point_centred(self.width_px, self.height_px)

    @property
    def K(self) -> np.ndarray:
        """3×3 intrinsic matrix, OpenCV convention."""
        cx, cy = self.principal_point_px
        f = self.fx_px
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        return np.asarray(self.distortion, dtype=np.float64)

    @property
    def aperture_radius_m(self) -> float:
        """Thin-lens aperture radius R = f / (2N); 0 for a pinhole (N = 0)."""
        return 0.0 if self.f_number == 0 else self.focal_length_m / (2.0 * self.f_number)

    @property
    def fov_x_deg(self) -> float:
        """Horizontal field of view of the sensor (not Mitsuba's 35 mm-equivalent focal length)."""
        return math.degrees(2.0 * math.atan(self.width_px * self.pitch_m / (2.0 * self.focal_length_m)))

    @property
    def shape(self) -> tuple[int, int]:
        return self.height_px, self.width_px

    def defocus_radius_px(self, distance_m: np.ndarray | float) -> np.ndarray | float:
        """Radius of the thin-lens blur disk, r = fx·R·|1/z_f − 1/z| (pixels)."""
        z = np.asarray(distance_m, dtype=np.float64)
        return self.fx_px * self.aperture_radius_m * np.abs(1.0 / self.focus_distance_m - 1.0 / z)

    # --- projection ----------------------------------------------------------
    def project(self, points_cam_m: np.ndarray, distorted: bool = True) -> np.ndarray:
        """Project (N, 3) camera-frame points to (N, 2) OpenCV pixel coordinates."""
        p = np.asarray(points_cam_m, dtype=np.float64).reshape(-1, 3)
        x, y = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
        if distorted:
            x, y = distort_normalized(x, y, self.distortion)
        cx, cy = self.principal_point_px
        return np.stack([self.fx_px * x + cx, self.fx_px * y + cy], axis=1)

    def undistort_pixels(self, pts_px: np.ndarray) -> np.ndarray:
        """Distorted pixel coords (N, 2) -> ideal (undistorted) pixel coords with the same K."""
        p = np.asarray(pts_px, dtype=np.float64).reshape(-1, 2)
        cx, cy = self.principal_point_px
        xu, yu = undistort_normalized((p[:, 0] - cx) / self.fx_px, (p[:, 1] - cy) / self.fx_px, self.distortion, 50)
        return np.stack([self.fx_px * xu + cx, self.fx_px * yu + cy], axis=1)

    # --- (de)serialisation ---------------------------------------------------
    def scaled(self, factor: int) -> "Camera":
        """The same optics with ``factor``× fewer pixels per side (pitch ×factor): same field of view."""
        require(self.width_px % factor == 0 and self.height_px % factor == 0,
                f"camera {self.name}: resolution not divisible by {factor}")
        return replace(self, width_px=self.width_px // factor, height_px=self.height_px // factor,
                       pitch_um=self.pitch_um * factor)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["distortion"] = {k: float(v) for k, v in zip(("k1", "k2", "p1", "p2", "k3"), self.distortion)}
        return d

    def ground_truth(self) -> dict:
        """What the JSON ground truth records about the camera."""
        cx, cy = self.principal_point_px
        return {
            "name": self.name,
            "width_px": self.width_px,
            "height_px": self.height_px,
            "pitch_um": self.pitch_um,
            "focal_length_mm": self.focal_length_mm,
            "f_number": self.f_number,
            "focus_distance_m": self.focus_distance_m,
            "aperture_radius_m": self.aperture_radius_m,
            "convention": "opencv: pixel (r, c) centre at x=c, y=r",
            "K": self.K.tolist(),
            "fx_px": self.fx_px,
            "fy_px": self.fx_px,
            "cx_px": cx,
            "cy_px": cy,
            "dist_coeffs_opencv": self.dist_coeffs.tolist(),
        }


def camera_from_dict(d: dict, name: str = "custom") -> Camera:
    """Build a camera from a spec table (as in ``assets/cameras/*.toml``)."""
    known = {"width_px", "height_px", "pitch_um", "focal_length_mm", "f_number", "focus_distance_m", "distortion", "name"}
    unknown = set(d) - known
    require(not unknown, f"camera {name}: unknown keys {sorted(unknown)} (known: {sorted(known)})")
    kw = dict(d)
    dist = kw.pop("distortion", {})
    if isinstance(dist, dict):
        bad = set(dist) - {"k1", "k2", "p1", "p2", "k3"}
        require(not bad, f"camera {name}: unknown distortion keys {sorted(bad)}")
        dist = tuple(float(dist.get(k, 0.0)) for k in ("k1", "k2", "p1", "p2", "k3"))
    kw["distortion"] = tuple(float(v) for v in dist)
    kw.setdefault("name", name)
    try:
        return Camera(**kw)
    except TypeError as exc:  # wrong value types
        raise InputError(f"camera {name}: {exc}") from None


def load_camera(name_or_path: str | Path = DEFAULT_CAMERA) -> Camera:
    """A camera from ``assets/cameras/<name>.toml`` or a TOML file path."""
    path = Path(name_or_path)
    if not path.suffix:
        path = ASSETS_DIR / "cameras" / f"{name_or_path}.toml"
    require(path.is_file(), f"camera spec {name_or_path!r} not found (looked for {path})")
    data = load_toml(path)
    return camera_from_dict(data.get("camera", data), name=path.stem)
