"""A Mitsuba sensor plugin: thin lens, exact Brown–Conrady distortion, lens PSF, falloff, motion.

Per film sample (in this order):

1. **PSF.**  The sample's pixel p and its stratified position s in the pixel are recovered
   exactly from the film coordinate; s is warped through the inverse CDF of the kernel
   K = box ⊗ PSF (``edgetruth.render.optics.psf``) to an offset z, and the ray goes through the sensor
   point p + z while the film still files the sample under p (box filter).  So the PSF
   convolves the irradiance before the pixel integrates it, using no extra random dimension.
   Without a PSF the ray goes through the film sample itself (the box alone).
2. **Distortion.**  The sensor point is mapped through the *inverse* distortion model
   (fixed-point iteration) to an ideal image point, which fixes the point on the focus plane;
   the ray runs from a uniformly sampled point of the aperture disk through it (Mitsuba's
   ``thinlens`` geometry: a planar focus surface at z = focus distance, image scale
   independent of focus).  Zero distortion and aperture: an ideal pinhole.
3. **Relative illumination.**  Each ray's weight is (1 + ρ²) cos⁴θ, θ the angle between the
   image-side ray (sensor point -> aperture point, lens at distance f) and the axis, ρ = R/f:
   its mean over the aperture is exactly the thin lens's irradiance falloff relative to the
   centre (``edgetruth.render.optics.prediction.relative_illumination``), times the shading polynomial.
   Mitsuba's own ``thinlens`` (like this plugin without it) gives none: weight 1.
4. **Motion.**  With a camera velocity the integrator samples a time t in [0, T) (T: exposure)
   and the camera sits at v·τ, rotated by ω·τ, τ = t − T/2: the world frame is the camera frame
   at mid-exposure.

Rays are generated directly in the OpenCV camera frame (x right, y down, z forward), which the
scenes use as their world frame.  The plugin is Python: it runs once per wavefront on the JIT
variants (fast) but once per *sample* on ``scalar_*`` (slow).
"""
from __future__ import annotations

import math

from edgetruth.conventions import MITSUBA_TO_CV_OFFSET_PX
from edgetruth.render.optics.distortion import is_zero, undistort_normalized
from edgetruth.render.optics.psf import PsfParams, psf_table

PLUGIN_NAME = "edgetruth_lens"
_registered: set[str] = set()


def _rodrigues(axis, angle, v, dr):
    """Rotate ``v`` by ``angle`` (array) about the unit ``axis`` (3 floats)."""
    import mitsuba as mi

    k = mi.Vector3f(*axis)
    c, s = dr.cos(angle), dr.sin(angle)
    return v * c + dr.cross(k, v) * s + k * (dr.dot(k, v) * (1.0 - c))


def register() -> str:
    """Register the plugin for the active variant (idempotent); returns its name."""
    import mitsuba as mi
    import drjit as dr

    variant = mi.variant()
    if variant in _registered:
        return PLUGIN_NAME
    scalar = variant.startswith("scalar")

    def film_coordinate(sample, size, offset):
        """The film coordinate a = offset + pixel + s exactly as the integrator formed it (float32),
        from sample = (a − offset) / size: the product is formed in double and rounded once."""
        if scalar:
            import numpy as np

            return float(np.float32(float(sample) * size)) + offset
        return mi.Float(mi.Float64(sample) * size) + offset

    class LensSensor(mi.Sensor):
        def __init__(self, props):
            super().__init__(props)
            self.fx = float(props.get("fx_px"))
            self.fy = float(props.get("fy_px", self.fx))
            self.cx = float(props.get("cx_px"))
            self.cy = float(props.get("cy_px"))
            self.coeffs = tuple(float(props.get(k, 0.0)) for k in ("k1", "k2", "p1", "p2", "k3"))
            self.distorted = not is_zero(self.coeffs)
            self.aperture_radius = float(props.get("aperture_radius_m", 0.0))
            self.focus_distance = float(props.get("focus_distance_m", 1.0))
            self.focal_length = float(props.get("focal_length_m", 1.0))
            self.half_diagonal = float(props.get("half_diagonal_px", 1.0))
            film = self.film()
            self.crop_offset = [float(v) for v in film.crop_offset()]
            self.crop_size = [float(v) for v in film.crop_size()]
            self.set_window(0, 0)
            # integrators draw an aperture sample only when the sensor asks for one
            self.m_needs_sample_3 = self.aperture_radius > 0.0
            params = PsfParams(cutoff_cy_px=float(props.get("psf_cutoff_cy_px", math.inf)),
                               sigma_px=float(props.get("psf_sigma_px", 0.0)),
                               sigma_growth=float(props.get("psf_sigma_growth", 0.0)),
                               olpf_px=float(props.get("psf_olpf_px", 0.0)),
                               sigma_y_px=float(props["psf_sigma_y_px"]) if "psf_sigma_y_px" in props
                               else None)
            self.table = psf_table(params)
            if self.table is not None:
                import numpy as np

                d, levels = self.table.density, list(self.table.field_heights_sq)
                if len(levels) == 1:  # the warp interpolates between >= 2 levels
                    d, levels = d[[0, 0]], [0.0, 1.0]
                self.warp = mi.MarginalContinuous2D1(np.ascontiguousarray(d, dtype=np.float32), [levels])
                self.psf_half = float(self.table.half_width_px)
            self.vignetting = bool(props.get("natural_vignetting", False))
            self.shading = (float(props.get("shading_a2", 0.0)), float(props.get("shading_a4", 0.0)))
            self.velocity = tuple(float(props.get(f"v{a}", 0.0)) for a in "xyz")
            omega = tuple(math.radians(float(props.get(f"w{a}", 0.0))) for a in "xyz")
            self.omega = math.sqrt(sum(w * w for w in omega))
            self.omega_axis = tuple(w / self.omega for w in omega) if self.omega > 0 else (0.0, 0.0, 1.0)
            self.moving = self.omega > 0 or any(v != 0 for v in self.velocity)
            self.mid_exposure = 0.5 * float(self.shutter_open_time())

        def set_window(self, x0: int, y0: int) -> None:
            """Film pixel (i, j) images full-frame pixel (x0 + i, y0 + j): a small film renders any window
            of the frame with one compiled kernel (the offset is an opaque JIT variable)."""
            self.window_px = (int(x0), int(y0))
            self.pixel_list = None
            if scalar:
                self.window = (float(x0), float(y0))
            else:
                self.window = (dr.opaque(mi.Float, float(x0)), dr.opaque(mi.Float, float(y0)))

        def set_pixels(self, xs, ys) -> None:
            """Film pixel (i, j) images full-frame pixel (xs[k], ys[k]), k = j * width + i (one per film
            pixel, integers): any set of pixels -- an outline's band -- in one render, with one compiled
            kernel (the lists are JIT arrays, not literals)."""
            n = int(self.crop_size[0] * self.crop_size[1])
            if len(xs) != n or len(ys) != n:
                raise ValueError(f"set_pixels: {n} pixels expected (one per film pixel), got {len(xs)}")
            self.window_px = None
            if scalar:
                self.pixel_list = ([float(x) for x in xs], [float(y) for y in ys])
            else:
                self.pixel_list = (mi.Float([float(x) for x in xs]), mi.Float([float(y) for y in ys]))

        def _film_pixel(self, u, v):
            """The film pixel of film coordinate (u, v) in pixel-list mode.  The integrator forms the sample
            position as pixel + jitter in float32, which rounds up to the next integer for a jitter within
            ~4e-6 of 1: on the last column or row that is one past the film, whose list index would read
            past the list (or, mid-film, another listed pixel far away).  Clamped: the sample sits on its
            pixel's far edge, as it would have."""
            w, h = self.crop_size
            return dr.minimum(dr.floor(u), w - 1.0), dr.minimum(dr.floor(v), h - 1.0)

        def _frame_pixel(self, pu, pv):
            """The frame pixel (column, row) of film pixel (pu, pv) (integers)."""
            if self.pixel_list is None:
                return pu + self.window[0], pv + self.window[1]
            w = int(self.crop_size[0])
            if scalar:
                k = int(pv) * w + int(pu)
                return self.pixel_list[0][k], self.pixel_list[1][k]
            k = mi.UInt32(pv) * w + mi.UInt32(pu)
            return dr.gather(mi.Float, self.pixel_list[0], k), dr.gather(mi.Float, self.pixel_list[1], k)

        def _sensor_point(self, position_sample):
            """OpenCV pixel coordinates of the point the ray leaves the sensor from."""
            u = film_coordinate(position_sample.x, self.crop_size[0], self.crop_offset[0])
            v = film_coordinate(position_sample.y, self.crop_size[1], self.crop_offset[1])
            if self.table is None:
                if self.pixel_list is None:
                    return u + self.window[0] + MITSUBA_TO_CV_OFFSET_PX, v + self.window[1] + MITSUBA_TO_CV_OFFSET_PX
                pu, pv = self._film_pixel(u, v)
                fu, fv = self._frame_pixel(pu, pv)
                return fu + (u - pu) + MITSUBA_TO_CV_OFFSET_PX, fv + (v - pv) + MITSUBA_TO_CV_OFFSET_PX
            if self.pixel_list is None:
                pu, pv = dr.floor(u), dr.floor(v)
            else:
                pu, pv = self._film_pixel(u, v)
            u, v = u - pu, v - pv  # the sample's position in its pixel
            pu, pv = self._frame_pixel(pu, pv)  # the pixel; its centre is (pu, pv) in OpenCV coordinates
            q = dr.minimum(((pu - self.cx) ** 2 + (pv - self.cy) ** 2) / self.half_diagonal ** 2, 1.0)
            z, _ = self.warp.sample(mi.Point2f(u, v), mi.Vector1f(q))
            return pu + self.psf_half * (2.0 * z.x - 1.0), pv + self.psf_half * (2.0 * z.y - 1.0)

        def sample_ray(self, time, wavelength_sample, position_sample, aperture_sample, active=True):
            xs, ys = self._sensor_point(position_sample)
            xd, yd = (xs - self.cx) / self.fx, (ys - self.cy) / self.fy
            x, y = undistort_normalized(xd, yd, self.coeffs) if self.distorted else (xd, yd)
            weight = 1.0
            if self.aperture_radius > 0.0:
                disk = mi.warp.square_to_uniform_disk_concentric(aperture_sample) * self.aperture_radius
                o = mi.Point3f(disk.x, disk.y, 0.0)
                focus = mi.Point3f(x * self.focus_distance, y * self.focus_distance, self.focus_distance)
                d = dr.normalize(focus - o)
                ax, ay = disk.x / self.focal_length, disk.y / self.focal_length
            else:
                o = mi.Point3f(0.0)
                d = dr.normalize(mi.Vector3f(x, y, 1.0))
                ax = ay = 0.0
            if self.vignetting:
                rho2 = (self.aperture_radius / self.focal_length) ** 2
                t2 = (ax + xd) ** 2 + (ay + yd) ** 2  # tan² of the image-side ray (the image is inverted)
                weight = (1.0 + rho2) / (1.0 + t2) ** 2
            if self.shading != (0.0, 0.0):
                h2 = ((xs - self.cx) ** 2 + (ys - self.cy) ** 2) / self.half_diagonal ** 2
                weight = weight * dr.maximum(0.0, 1.0 + h2 * (self.shading[0] + h2 * self.shading[1]))
            if self.moving:
                tau = time - self.mid_exposure
                if self.omega > 0:
                    o = mi.Point3f(_rodrigues(self.omega_axis, self.omega * tau, mi.Vector3f(o), dr))
                    d = _rodrigues(self.omega_axis, self.omega * tau, d, dr)
                o = o + mi.Vector3f(*self.velocity) * tau
            ray = mi.Ray3f(o, d)
            ray.time = time
            return ray, mi.Spectrum(weight)

        def sample_ray_differential(self, time, wavelength_sample, position_sample, aperture_sample, active=True):
            ray, weight = self.sample_ray(time, wavelength_sample, position_sample, aperture_sample, active)
            return mi.RayDifferential3f(ray), weight

        def bbox(self):
            return mi.ScalarBoundingBox3f(mi.ScalarPoint3f(0.0))

        def to_string(self):
            return f"LensSensor[fx={self.fx}, fy={self.fy}, R={self.aperture_radius}, zf={self.focus_distance}]"

    mi.register_sensor(PLUGIN_NAME, lambda props: LensSensor(props))
    _registered.add(variant)
    return PLUGIN_NAME


def sensor_dict(camera, sampler: dict, crop: tuple[int, int, int, int] | None = None,
                exposure_s: float = 0.0, window: tuple[int, int] | None = None) -> dict:
    """The scene-dict entry of the sensor for ``camera`` (a ``edgetruth.render.optics.camera.Camera``).

    ``crop`` = (x0, y0, width, height) in pixels renders only that window of the full film;
    ``window`` = (width, height): a film of that size whose position in the frame the sensor's
    ``set_window`` moves (``edgetruth.render.scene.edge_band``); ``exposure_s`` is the shutter time the
    camera's motion (if any) spans.
    """
    from edgetruth.render.optics.psf import psf_params

    cx, cy = camera.principal_point_px
    film = {
        "type": "hdrfilm",
        "width": camera.width_px,
        "height": camera.height_px,
        "rfilter": {"type": "box"},  # the default Gaussian smears an edge over 3 px
        "component_format": "float32",
        "pixel_format": "rgb",
    }
    if crop is not None:
        x0, y0, w, h = crop
        film.update(crop_offset_x=int(x0), crop_offset_y=int(y0), crop_width=int(w), crop_height=int(h))
    if window is not None:
        film.update(width=int(window[0]), height=int(window[1]))
    k1, k2, p1, p2, k3 = camera.distortion
    p = psf_params(camera)
    out = {
        "type": register(),
        "fx_px": camera.fx_px, "fy_px": camera.fy_px, "cx_px": cx, "cy_px": cy,
        "k1": k1, "k2": k2, "p1": p1, "p2": p2, "k3": k3,
        "aperture_radius_m": camera.aperture_radius_m,
        "focus_distance_m": camera.focus_distance_m,
        "focal_length_m": camera.focal_length_m,
        "half_diagonal_px": camera.half_diagonal_px,
        "psf_cutoff_cy_px": p.cutoff_cy_px if math.isfinite(p.cutoff_cy_px) else math.inf,
        "psf_sigma_px": p.sigma_px, "psf_sigma_growth": p.sigma_growth, "psf_olpf_px": p.olpf_px,
        "natural_vignetting": bool(camera.natural_vignetting),
        "shading_a2": camera.shading_a2, "shading_a4": camera.shading_a4,
        "film": film,
        "sampler": sampler,
    }
    if p.sigma_y_px is not None:  # an anisotropic aberration (absent otherwise: the same scene dict as before)
        out["psf_sigma_y_px"] = p.sigma_y_px
    if camera.moving:
        if exposure_s <= 0:
            raise ValueError("a moving camera needs the exposure time")
        out.update(shutter_open=0.0, shutter_close=float(exposure_s),
                   **{f"v{a}": float(v) for a, v in zip("xyz", camera.velocity_m_s)},
                   **{f"w{a}": float(w) for a, w in zip("xyz", camera.angular_velocity_deg_s)})
    return out
