"""The camera: intrinsics, thin-lens aperture, Brown–Conrady distortion, lens PSF, relative
illumination and camera motion from a spec.

Intrinsics: by default fx = fy = f / pitch and the principal point at the image centre
(cx = W/2 − 1/2, cy = H/2 − 1/2).  A camera may state them instead (``fx_px``, ``fy_px``,
``cx_px``, ``cy_px``: e.g. a calibrated camera's K); the focal length in millimetres then follows
from fx (f = fx · pitch) unless given, when the two must agree.  fy ≠ fx means non-square
pixels (``pitch_um`` is the pitch along x; the vertical pitch is pitch · fx / fy); the lens PSF
is defined in pixels (its size in µm is divided by the x pitch).  Skew is not modelled.

The Gaussian aberration may be anisotropic: ``aberration_sigma_y_um`` (default: none, i.e. equal to
``aberration_sigma_um``) is its σ along the image's y axis, ``aberration_sigma_um`` then the σ along
x (``edgetruth.render.optics.psf``).

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
from edgetruth.fileio import read_toml
from edgetruth.render.optics.distortion import distort_normalized, undistort_normalized
from edgetruth.render.optics.prediction import optics_ground_truth
from edgetruth.render.schema import Key, parse_table

DEFAULT_CAMERA = "default"
#: A stated fx and the focal length / pitch must agree to this relative tolerance.
INTRINSICS_RTOL = 1e-6


@dataclass(frozen=True)
class Camera:
    """A thin-lens camera: square pixels and a centred optical axis unless its intrinsics say otherwise."""

    width_px: int = 1280
    height_px: int = 1024
    pitch_um: float = 4.8
    focal_length_mm: float = 8.0
    f_number: float = 4.0
    focus_distance_m: float = 1.5
    #: OpenCV order (k1, k2, p1, p2, k3).
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    #: Lens PSF (``edgetruth.render.optics.psf``): Airy diffraction at this wavelength and the f-number
    #: (0: none), a Gaussian aberration sigma(h) = sigma * (1 + growth * h^2) at field height h
    #: (0 centre, 1 image corner), and a 4-dot birefringent low-pass filter of this split.
    diffraction_wavelength_nm: float = 550.0
    aberration_sigma_um: float = 0.0
    aberration_sigma_growth: float = 0.0
    olpf_split_um: float = 0.0
    #: Relative illumination: the thin lens's exact natural falloff (cos^4 per ray) times
    #: 1 + a2 h^2 + a4 h^4 (lens shading).
    natural_vignetting: bool = True
    shading_a2: float = 0.0
    shading_a4: float = 0.0
    #: Camera motion during the exposure (camera frame at mid-exposure): linear and angular velocity.
    velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    angular_velocity_deg_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: Stated intrinsics (pixels, OpenCV convention); None: derived (fx = fy = f / pitch, centred).
    #: With ``focal_x_px`` set, ``focal_length_mm`` must equal fx · pitch (``Camera.from_intrinsics``).
    focal_x_px: float | None = None
    focal_y_px: float | None = None
    principal_x_px: float | None = None
    principal_y_px: float | None = None
    #: An anisotropic Gaussian aberration: its sigma along the image y axis (``aberration_sigma_um`` is then
    #: the sigma along x); None: isotropic.  Left out of ``to_dict`` when None (unchanged spec hashes).
    aberration_sigma_y_um: float | None = None
    name: str = field(default="custom", compare=False)

    def __post_init__(self) -> None:
        require(self.width_px > 0 and self.height_px > 0, f"camera {self.name}: resolution must be positive")
        require(self.pitch_um > 0 and self.focal_length_mm > 0, f"camera {self.name}: pitch and focal length must be positive")
        require(self.f_number >= 0, f"camera {self.name}: f_number must be >= 0 (0 = pinhole)")
        require(self.focus_distance_m > 0, f"camera {self.name}: focus_distance_m must be positive")
        require(len(self.distortion) == 5, f"camera {self.name}: distortion needs 5 coefficients (k1, k2, p1, p2, k3)")
        require(self.diffraction_wavelength_nm >= 0 and self.aberration_sigma_um >= 0 and self.olpf_split_um >= 0,
                f"camera {self.name}: PSF parameters must be >= 0")
        require(self.aberration_sigma_y_um is None or self.aberration_sigma_y_um >= 0,
                f"camera {self.name}: aberration_sigma_y_um must be >= 0")
        require(self.aberration_sigma_growth >= -1.0, f"camera {self.name}: aberration_sigma_growth must be >= -1 "
                "(sigma may not turn negative at the corner)")
        require(len(self.velocity_m_s) == 3 and len(self.angular_velocity_deg_s) == 3,
                f"camera {self.name}: velocities need 3 components (x, y, z in the camera frame)")
        for k in ("focal_x_px", "focal_y_px"):
            v = getattr(self, k)
            require(v is None or (math.isfinite(v) and v > 0), f"camera {self.name}: {k} must be positive")
        if self.focal_x_px is not None:
            derived = self.focal_length_m / self.pitch_m
            require(abs(derived / self.focal_x_px - 1.0) <= INTRINSICS_RTOL,
                    f"camera {self.name}: focal_length_mm = {self.focal_length_mm:g} and pitch_um = {self.pitch_um:g} "
                    f"give fx = {derived:.6g} px, not fx_px = {self.focal_x_px:g}; leave focal_length_mm out (it "
                    "follows from fx_px x pitch_um) or make the two agree")
        for k, n in (("principal_x_px", self.width_px), ("principal_y_px", self.height_px)):
            v = getattr(self, k)
            require(v is None or (math.isfinite(v) and -0.5 <= v <= n - 0.5),
                    f"camera {self.name}: {k} = {v} must lie on the image, in [-0.5, {n - 0.5}] px")

    @classmethod
    def from_intrinsics(cls, fx_px: float, fy_px: float | None = None, cx_px: float | None = None,
                        cy_px: float | None = None, **kw) -> "Camera":
        """A camera with stated intrinsics; its focal length (mm) follows from fx and the pitch."""
        pitch = kw.get("pitch_um", cls.pitch_um)
        kw.setdefault("focal_length_mm", fx_px * pitch * 1e-3)
        return cls(focal_x_px=float(fx_px), focal_y_px=None if fy_px is None else float(fy_px),
                   principal_x_px=None if cx_px is None else float(cx_px),
                   principal_y_px=None if cy_px is None else float(cy_px), **kw)

    # --- derived quantities -------------------------------------------------
    @property
    def pitch_m(self) -> float:
        return self.pitch_um * 1e-6

    @property
    def focal_length_m(self) -> float:
        return self.focal_length_mm * 1e-3

    @property
    def fx_px(self) -> float:
        if self.focal_x_px is not None:
            return float(self.focal_x_px)
        return focal_length_px(self.focal_length_m, self.pitch_m)

    @property
    def fy_px(self) -> float:
        return self.fx_px if self.focal_y_px is None else float(self.focal_y_px)

    @property
    def principal_point_px(self) -> tuple[float, float]:
        cx, cy = principal_point_centred(self.width_px, self.height_px)
        return (cx if self.principal_x_px is None else float(self.principal_x_px),
                cy if self.principal_y_px is None else float(self.principal_y_px))

    @property
    def stated_intrinsics(self) -> bool:
        """True when any of fx, fy, cx, cy is stated rather than derived."""
        return any(v is not None for v in (self.focal_x_px, self.focal_y_px, self.principal_x_px,
                                           self.principal_y_px))

    @property
    def K(self) -> np.ndarray:
        """3×3 intrinsic matrix, OpenCV convention (no skew)."""
        cx, cy = self.principal_point_px
        return np.array([[self.fx_px, 0.0, cx], [0.0, self.fy_px, cy], [0.0, 0.0, 1.0]])

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

    @property
    def moving(self) -> bool:
        return any(v != 0 for v in self.velocity_m_s) or any(w != 0 for w in self.angular_velocity_deg_s)

    @property
    def half_diagonal_px(self) -> float:
        """Half the image diagonal (field height 1), pixels: the distance from a centred principal point
        to the image corner (with a stated principal point the corners' distances differ; field
        heights stay normalised by this)."""
        return math.hypot(self.width_px / 2.0, self.height_px / 2.0)

    def ideal_optics(self) -> "Camera":
        """The same geometry with a perfect lens: no PSF, no falloff or shading, no motion (thin-lens
        defocus and distortion stay)."""
        return replace(self, diffraction_wavelength_nm=0.0, aberration_sigma_um=0.0, aberration_sigma_growth=0.0,
                       aberration_sigma_y_um=None, olpf_split_um=0.0, natural_vignetting=False, shading_a2=0.0, shading_a4=0.0,
                       velocity_m_s=(0.0, 0.0, 0.0), angular_velocity_deg_s=(0.0, 0.0, 0.0))

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
        return np.stack([self.fx_px * x + cx, self.fy_px * y + cy], axis=1)

    def rays(self, pts_px: np.ndarray) -> np.ndarray:
        """Distorted pixel coords (N, 2) -> the camera-frame directions (N, 3) that image there, (x, y, 1): the
        inverse of ``project``."""
        p = np.asarray(pts_px, dtype=np.float64).reshape(-1, 2)
        cx, cy = self.principal_point_px
        xu, yu = undistort_normalized((p[:, 0] - cx) / self.fx_px, (p[:, 1] - cy) / self.fy_px, self.distortion, 50)
        return np.column_stack([xu, yu, np.ones(len(xu))])

    def undistort_pixels(self, pts_px: np.ndarray) -> np.ndarray:
        """Distorted pixel coords (N, 2) -> ideal (undistorted) pixel coords with the same K."""
        d = self.rays(pts_px)
        cx, cy = self.principal_point_px
        return np.stack([self.fx_px * d[:, 0] + cx, self.fy_px * d[:, 1] + cy], axis=1)

    # --- (de)serialisation ---------------------------------------------------
    def scaled(self, factor: int) -> "Camera":
        """The same optics with ``factor``× fewer pixels per side (pitch ×factor): same field of view."""
        require(self.width_px % factor == 0 and self.height_px % factor == 0,
                f"camera {self.name}: resolution not divisible by {factor}")
        stated = {}
        for k in ("focal_x_px", "focal_y_px"):
            if getattr(self, k) is not None:
                stated[k] = getattr(self, k) / factor
        for k in ("principal_x_px", "principal_y_px"):  # pixel centre c of the fine grid -> (c + 1/2) / factor - 1/2
            if getattr(self, k) is not None:
                stated[k] = (getattr(self, k) + 0.5) / factor - 0.5
        return replace(self, width_px=self.width_px // factor, height_px=self.height_px // factor,
                       pitch_um=self.pitch_um * factor, **stated)

    def to_dict(self) -> dict:
        d = asdict(self)
        for k in ("focal_x_px", "focal_y_px", "principal_x_px", "principal_y_px", "aberration_sigma_y_um"):
            if d[k] is None:  # derived / off: not part of a default camera's identity (unchanged spec hashes)
                del d[k]
        d["distortion"] = {k: float(v) for k, v in zip(("k1", "k2", "p1", "p2", "k3"), self.distortion)}
        d["velocity_m_s"] = list(self.velocity_m_s)
        d["angular_velocity_deg_s"] = list(self.angular_velocity_deg_s)
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
            "fy_px": self.fy_px,
            "cx_px": cx,
            "cy_px": cy,
            "dist_coeffs_opencv": self.dist_coeffs.tolist(),
            "optics": self._optics_truth(),
        }

    def _optics_truth(self) -> dict:
        """``optics_ground_truth``, plus the y axis of an anisotropic aberration (only then: the JSON of an
        isotropic camera is unchanged)."""
        out = optics_ground_truth(self)
        if self.aberration_sigma_y_um is not None:
            from edgetruth.render.optics import mtf
            from edgetruth.render.optics.psf import psf_params

            p = psf_params(self)
            out["psf"]["aberration_sigma_y_um"] = self.aberration_sigma_y_um
            out["psf"]["aberration_sigma_y_px_centre"] = p.sigma_y_at(0.0)
            out["psf"]["aberration_sigma_y_px_corner"] = p.sigma_y_at(1.0)
            out["psf"]["model"] += ("; the Gaussian is elliptical: sigma along x = aberration_sigma_um, along y = "
                                    "aberration_sigma_y_um (both times 1 + g h^2)")
            out["mtf50_centre_y_cy_px"] = mtf.mtf50(lambda nu: p.otf(0.0 * nu, nu, 0.0))
            out["mtf50_corner_y_cy_px"] = mtf.mtf50(lambda nu: p.otf(0.0 * nu, nu, 1.0))
            out["mtf50_meaning"] += "; mtf50_*_y_cy_px: along the image y axis"
        return out


_D = Camera()
#: The ``[camera]`` table of a camera TOML.  ``per_group``: a spec's [[group]] may override it
#: (``camera = { f_number = 2.8 }``) to sweep it; the others fix the intrinsics of the whole spec.
CAMERA_KEYS = [
    Key("width_px", "int", _D.width_px, "px", "image width", 8, 16384),
    Key("height_px", "int", _D.height_px, "px", "image height", 8, 16384),
    Key("pitch_um", "float", _D.pitch_um, "um", "pixel pitch (square pixels, 100 % fill factor)", 0.1, 1000.0),
    Key("focal_length_mm", "float", _D.focal_length_mm, "mm", "focal length f; fx = fy = f / pitch unless fx_px "
        "/ fy_px are given (then f = fx_px x pitch follows from them when left out)", 0.1, 10000.0),
    Key("fx_px", "float", None, "px", "focal length in pixels along x (a calibrated K's fx); default: f / pitch",
        1.0, 1e7),
    Key("fy_px", "float", None, "px", "focal length in pixels along y (fy != fx: non-square pixels, vertical "
        "pitch = pitch x fx / fy); default: fx", 1.0, 1e7),
    Key("cx_px", "float", None, "px", "principal point x (OpenCV: pixel centres at integers); default: the image "
        "centre W/2 - 1/2; must lie on the image", -0.5, 16384.0),
    Key("cy_px", "float", None, "px", "principal point y; default: H/2 - 1/2; must lie on the image", -0.5, 16384.0),
    Key("f_number", "float", _D.f_number, "", "f-number N; thin-lens aperture radius R = f / (2N); 0 = pinhole",
        0.0, 1000.0, per_group=True, check=lambda v: None if v == 0 or v >= 0.5 else "use 0 (pinhole) or >= 0.5"),
    Key("focus_distance_m", "float", _D.focus_distance_m, "m", "distance of the plane in focus", 1e-3, 1e6,
        per_group=True),
    Key("distortion", "table", {}, "", "Brown-Conrady coefficients {k1, k2, p1, p2, k3} (OpenCV order, "
        "normalised coordinates); missing ones are 0"),
    Key("diffraction_wavelength_nm", "float", _D.diffraction_wavelength_nm, "nm", "wavelength of the Airy "
        "diffraction PSF at the f-number (cutoff p/(lambda N)); 0 = no diffraction", 0.0, 20000.0, per_group=True),
    Key("aberration_sigma_um", "float", _D.aberration_sigma_um, "um", "Gaussian aberration blur sigma on the "
        "sensor at the image centre", 0.0, 1000.0, per_group=True),
    Key("aberration_sigma_y_um", "float", None, "um", "anisotropic aberration: the Gaussian's sigma along the "
        "image y axis (aberration_sigma_um is then its sigma along x); default: isotropic (= aberration_sigma_um)",
        0.0, 1000.0, per_group=True),
    Key("aberration_sigma_growth", "float", _D.aberration_sigma_growth, "", "growth g of the aberration with "
        "field height h (0 centre, 1 corner): sigma(h) = sigma * (1 + g h^2)", -1.0, 100.0, per_group=True),
    Key("olpf_split_um", "float", _D.olpf_split_um, "um", "4-dot birefringent low-pass filter: dots at "
        "(+-d/2, +-d/2); MTF cos(pi nu_x d) cos(pi nu_y d); 0 = none", 0.0, 1000.0, per_group=True),
    Key("natural_vignetting", "bool", _D.natural_vignetting, "", "the thin lens's natural falloff: each ray "
        "weighted by cos^4 of its angle on the sensor (exact relative illumination of a disk aperture)",
        per_group=True),
    Key("shading_a2", "float", _D.shading_a2, "", "lens shading: relative illumination times "
        "1 + a2 h^2 + a4 h^4 (h: field height, 1 at the corner)", -1.0, 10.0, per_group=True),
    Key("shading_a4", "float", _D.shading_a4, "", "lens shading h^4 coefficient (see shading_a2)", -1.0, 10.0,
        per_group=True),
    Key("velocity_m_s", "vec3", list(_D.velocity_m_s), "m/s", "camera velocity [vx, vy, vz] during the "
        "exposure (camera frame: x right, y down, z forward); a target moving at u is the camera at -u",
        -1e3, 1e3, per_group=True),
    Key("angular_velocity_deg_s", "vec3", list(_D.angular_velocity_deg_s), "deg/s", "camera angular velocity "
        "[wx, wy, wz] about its centre of projection during the exposure (camera frame)", -1e5, 1e5,
        per_group=True),
]
DISTORTION_KEYS = [Key(k, "float", 0.0, "", f"distortion coefficient {k}", -10.0, 10.0)
                   for k in ("k1", "k2", "p1", "p2", "k3")]
MAX_PIXELS = 1 << 27  # the largest image edgetruth reads back (``edgetruth.image_io.MAX_IMAGE_PIXELS``)


#: camera TOML key -> ``Camera`` field of the stated intrinsics
_STATED = {"fx_px": "focal_x_px", "fy_px": "focal_y_px", "cx_px": "principal_x_px", "cy_px": "principal_y_px"}


def _tuples(v: dict) -> dict:
    for k in ("velocity_m_s", "angular_velocity_deg_s"):
        if k in v:
            v[k] = tuple(v[k])
    return v


def check_optics(cam: Camera, where: str) -> None:
    """The lens PSF must be one the renderer can sample (an OLPF alone is not band-limited)."""
    sy = cam.aberration_sigma_y_um
    if sy is not None and min(sy, cam.aberration_sigma_um) == 0 and max(sy, cam.aberration_sigma_um) > 0 and (
            cam.diffraction_wavelength_nm == 0 or cam.f_number == 0):
        raise InputError(f"{where}: aberration_sigma_um = {cam.aberration_sigma_um} and aberration_sigma_y_um = {sy}: "
                         "a Gaussian blurred along one axis only needs diffraction (diffraction_wavelength_nm > 0 and "
                         "f_number > 0) to limit the other; give both sigmas > 0 or add diffraction")
    if cam.olpf_split_um > 0 and cam.aberration_sigma_um == 0 and (cam.diffraction_wavelength_nm == 0
                                                                    or cam.f_number == 0):
        raise InputError(f"{where}: olpf_split_um = {cam.olpf_split_um} needs diffraction "
                         "(diffraction_wavelength_nm > 0 and f_number > 0) or aberration_sigma_um > 0; add one")


def camera_from_dict(d: dict, name: str = "custom", where: str | None = None) -> Camera:
    """A camera from a ``[camera]`` table (as in ``assets/cameras/*.toml``), every value checked."""
    where = where or f"camera {name}"
    v = _tuples(parse_table(d, CAMERA_KEYS, where))
    dist = parse_table(v.pop("distortion"), DISTORTION_KEYS, f"{where} distortion")
    if v["width_px"] * v["height_px"] > MAX_PIXELS:
        raise InputError(f"{where}: {v['width_px']} x {v['height_px']} px exceeds {MAX_PIXELS:,} pixels; "
                         "use a smaller resolution (or camera_scale)")
    stated = {field_: v.pop(key) for key, field_ in _STATED.items()}
    if stated["focal_x_px"] is not None:
        derived = v["focal_length_mm"] * 1e-3 / (v["pitch_um"] * 1e-6)
        if "focal_length_mm" not in d:
            v["focal_length_mm"] = stated["focal_x_px"] * v["pitch_um"] * 1e-3
        elif abs(derived / stated["focal_x_px"] - 1.0) > INTRINSICS_RTOL:
            raise InputError(f"{where}: fx_px = {stated['focal_x_px']:g} but focal_length_mm / pitch_um give "
                             f"{derived:.6g} px; leave focal_length_mm out (it follows from fx_px x pitch_um) or "
                             "make the two agree")
    for key, n in (("cx_px", v["width_px"]), ("cy_px", v["height_px"])):
        c = stated[_STATED[key]]
        if c is not None and not -0.5 <= c <= n - 0.5:
            raise InputError(f"{where}: {key} = {c:g}: the principal point must lie on the image, in "
                             f"[-0.5, {n - 0.5:g}] px")
    cam = Camera(**v, **stated, distortion=tuple(dist[k] for k in ("k1", "k2", "p1", "p2", "k3")), name=name)
    check_optics(cam, where)
    return cam


def camera_overrides(d: dict, where: str) -> dict:
    """Checked per-group camera overrides (only keys marked ``per_group``)."""
    allowed = [k for k in CAMERA_KEYS if k.per_group]
    try:
        return _tuples(parse_table(d, allowed, where, defaults=False))
    except InputError as exc:
        fixed = sorted(set(d) & {k.name for k in CAMERA_KEYS if not k.per_group})
        if fixed:
            raise InputError(f"{where}: {', '.join(fixed)} fix the intrinsics of the whole spec and cannot be "
                             f"overridden per group (a group may override {', '.join(k.name for k in allowed)}); "
                             "use another spec for another camera") from None
        raise exc


def resolve_camera_path(ref: str, base_dir: Path | None = None) -> Path:
    """A camera reference: a shipped name (``default``) or a TOML path (relative to ``base_dir``,
    the folder of the spec that names it)."""
    from edgetruth.resources import shipped_camera, shipped_camera_names

    if not ref.endswith(".toml") and "/" not in ref and "\\" not in ref:
        local = Path(ref).expanduser() if base_dir is None else base_dir / Path(ref).expanduser()
        if ref not in shipped_camera_names() and (local.exists() or local.is_symlink()):
            what = ("a folder, not a camera file" if local.is_dir()
                    else f"a file, but a camera file's name ends in .toml (rename it {Path(ref).stem}.toml)")
            raise InputError(f"camera {ref!r}: {local} is {what}; name a camera TOML file, or a shipped camera: "
                             f"{', '.join(shipped_camera_names())}")
        return shipped_camera(ref)
    p = Path(ref).expanduser()
    if not p.is_absolute() and base_dir is not None:
        p = base_dir / p
    return p


def load_camera(ref: str | Path = DEFAULT_CAMERA, base_dir: Path | None = None) -> Camera:
    """A camera from a shipped name or a TOML file (``[camera]`` table, or the keys at top level)."""
    path = resolve_camera_path(str(ref), base_dir)
    if not path.exists():
        raise InputError(f"camera file {path} not found (a relative path is relative to the spec's folder); "
                         "fix the path or use a shipped camera name")
    data = read_toml(path)
    table = data.get("camera", data) if isinstance(data, dict) else data
    return camera_from_dict(table, name=path.stem, where=f"{path} [camera]")
