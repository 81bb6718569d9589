"""A Mitsuba sensor plugin: a thin-lens camera with exact Brown–Conrady distortion.

Each film sample (pixel position) is mapped through the *inverse* distortion
model (fixed-point iteration) to an ideal image point, which fixes the point on
the focus plane; the ray runs from a uniformly sampled point of the aperture
disk through that point (Mitsuba's ``thinlens`` geometry: a planar focus surface
at z = focus distance, image scale independent of focus).  With zero distortion
and zero aperture this is an ideal pinhole.

Rays are generated directly in the OpenCV camera frame (x right, y down, z
forward), which the scenes use as their world frame.  The plugin is Python: it
runs once per wavefront on the JIT variants (fast) but once per *sample* on
``scalar_*`` (slow).
"""
from __future__ import annotations

from edgetruth.conventions import MITSUBA_TO_CV_OFFSET_PX
from edgetruth.render.distortion import undistort_normalized, is_zero

PLUGIN_NAME = "edgetruth_lens"
_registered: set[str] = set()


def register() -> str:
    """Register the plugin for the active variant (idempotent); returns its name."""
    import mitsuba as mi
    import drjit as dr

    variant = mi.variant()
    if variant in _registered:
        return PLUGIN_NAME

    class LensSensor(mi.Sensor):
        def __init__(self, props):
            super().__init__(props)
            self.fx = float(props.get("fx_px"))
            self.cx = float(props.get("cx_px"))
            self.cy = float(props.get("cy_px"))
            self.coeffs = tuple(float(props.get(k, 0.0)) for k in ("k1", "k2", "p1", "p2", "k3"))
            self.distorted = not is_zero(self.coeffs)
            self.aperture_radius = float(props.get("aperture_radius_m", 0.0))
            self.focus_distance = float(props.get("focus_distance_m", 1.0))
            film = self.film()
            self.crop_offset = [float(v) for v in film.crop_offset()]
            self.crop_size = [float(v) for v in film.crop_size()]
            # integrators draw an aperture sample only when the sensor asks for one
            self.m_needs_sample_3 = self.aperture_radius > 0.0

        def _ideal_point(self, position_sample):
            # position_sample is relative to the crop window; make it a full-film coordinate
            u = self.crop_offset[0] + position_sample.x * self.crop_size[0] + MITSUBA_TO_CV_OFFSET_PX
            v = self.crop_offset[1] + position_sample.y * self.crop_size[1] + MITSUBA_TO_CV_OFFSET_PX
            xd = (u - self.cx) / self.fx
            yd = (v - self.cy) / self.fx
            if self.distorted:
                return undistort_normalized(xd, yd, self.coeffs)
            return xd, yd

        def sample_ray(self, time, wavelength_sample, position_sample, aperture_sample, active=True):
            x, y = self._ideal_point(position_sample)
            if self.aperture_radius > 0.0:
                disk = mi.warp.square_to_uniform_disk_concentric(aperture_sample) * self.aperture_radius
                o = mi.Point3f(disk.x, disk.y, 0.0)
                focus = mi.Point3f(x * self.focus_distance, y * self.focus_distance, self.focus_distance)
                d = dr.normalize(focus - o)
            else:
                o = mi.Point3f(0.0)
                d = dr.normalize(mi.Vector3f(x, y, 1.0))
            ray = mi.Ray3f(o, d)
            ray.time = time
            return ray, mi.Spectrum(1.0)

        def sample_ray_differential(self, time, wavelength_sample, position_sample, aperture_sample, active=True):
            ray, weight = self.sample_ray(time, wavelength_sample, position_sample, aperture_sample, active)
            return mi.RayDifferential3f(ray), weight

        def bbox(self):
            return mi.ScalarBoundingBox3f(mi.ScalarPoint3f(0.0))

        def to_string(self):
            return f"LensSensor[fx={self.fx}, R={self.aperture_radius}, zf={self.focus_distance}]"

    mi.register_sensor(PLUGIN_NAME, lambda props: LensSensor(props))
    _registered.add(variant)
    return PLUGIN_NAME


def sensor_dict(camera, sampler: dict, crop: tuple[int, int, int, int] | None = None) -> dict:
    """The scene-dict entry of the sensor for ``camera`` (a ``edgetruth.render.camera.Camera``).

    ``crop`` = (x0, y0, width, height) in pixels renders only that window of the full film.
    """
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
    k1, k2, p1, p2, k3 = camera.distortion
    return {
        "type": register(),
        "fx_px": camera.fx_px, "cx_px": cx, "cy_px": cy,
        "k1": k1, "k2": k2, "p1": p1, "p2": p2, "k3": k3,
        "aperture_radius_m": camera.aperture_radius_m,
        "focus_distance_m": camera.focus_distance_m,
        "film": film,
        "sampler": sampler,
    }
