"""Mitsuba scenes, loaded ONCE per process and re-posed with ``mi.traverse`` + ``update``.

(Repeated ``mi.load_dict`` leaks memory: mitsuba3 issue 1890.)

Target scene: a white matte board facing the camera with four targets, of which
the active one is placed flush on the board (10 µm stand-off, only to avoid
coplanar surfaces; a stand-off casts ambient-occlusion shading that moves the
edge) and the others are parked out of sight behind the camera:
T1 black matte square, T2 black matte disk, T3 gray matte square, T4 glossy black
square (rough plastic: specular highlights from the light).

A target group with a scene of its own (``edgetruth.render.scene.shapes.TargetScene``: the shape catalogue,
materials, lights) renders through ``SceneRig``, which ``TargetRig.set_state`` loads on first use (one
per scene, with the same camera, settings, crop and window); at equal emitted radiance it renders the
T1-T4 presets bit for bit as the fixed scene does.

Checkerboard scene: a white plate with black matte squares (one mesh with an explicit diffuse
BSDF of ``CHECKER_BLACK_REFLECTANCE``, its triangles facing the camera), flush likewise.  A board of
squares (``SquareBoard``) is the same scene with its own quads, plate and reflectances.

Light: one square area light beside the camera (behind its image plane, so never
in view; ``LIGHT_OFFSET_M`` unless a group places it), aimed at the board centre; its radiance is set so that the board's
irradiance at its centre equals the requested ``irradiance_w_m2`` whatever the
distance (one light: emitter selection adds no Monte-Carlo noise).
The world frame is the OpenCV camera frame (see ``edgetruth.render.scene.pose``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgetruth.render.optics.camera import Camera
from edgetruth.render.optics.lens_sensor import sensor_dict
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.sample_passes import render_in_passes
from edgetruth.render.scene.targets import (BOARD_HALF_SIZE_M, BOARD_REFLECTANCE, CHECKER_BLACK_REFLECTANCE,
                                      TARGET_STANDOFF_M, TARGETS, Checkerboard)

#: One shape per target, each with a fixed BSDF (the loader merges identical BSDFs, so their
#: parameters cannot be changed independently through ``traverse``).
_SHAPE_KEY = {"T1": "square_black", "T2": "disk_black", "T3": "square_gray", "T4": "square_glossy"}

LIGHT_OFFSET_M = np.array([0.0, -0.15, -0.05])  # above the camera, behind its image plane
LIGHT_HALF_SIZE_M = 0.025  # small: less MC noise (BRDF and geometry vary less across it)
_PARKED = np.diag([1e-3, 1e-3, 1e-3, 1.0]) @ np.array(  # tiny, far behind the camera, facing away
    [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -1e4], [0, 0, 0, 1]], dtype=float)


@dataclass(frozen=True)
class RenderSettings:
    """Monte-Carlo settings: flat regions at ``spp``, the band around a target's outline at ``edge_spp``
    (the defaults of a spec; the shipped specs use the orthogonal sampler at 25/2209 spp: docs/optics.md)."""

    spp: int = 64
    sampler: str = "multijitter"
    samples_per_pass: int = 0  # 0: all in one pass (JIT memory ~ pixels × spp)
    #: the shutter time rays are spread over (a moving camera only; 0: static)
    exposure_s: float = 0.0
    #: spp of the pixels near a target's outline (``edgetruth.render.scene.edge_band``); 0: none
    edge_spp: int = 0
    #: spp of checkerboard images; 0: ``spp``
    checkerboard_spp: int = 0
    #: the edge band: "path" (path-traced at ``edge_spp``, the reference), "analytic" (the board and
    #: the target's material rendered without an edge at ``edge_spp``, composited with the exact
    #: lens-weighted coverage: ``edgetruth.render.scene.edge_coverage``) or "frame" (that composite over
    #: the whole frame, the shading rendered on a grid and interpolated: ``shading_frame``)
    edge_mode: str = "path"
    #: ``edge_mode = "frame"``: the shading grid's node spacing, px (``edgetruth.render.scene.shading_frame``)
    shading_step_px: int = 16
    #: board images (checkerboard, squares): "path" (the full frame path-traced, the reference) or "frame" (the
    #: plate's shading on a grid, composited with the plate's and the squares' exact coverage: ``board_frame``)
    board_mode: str = "path"

    def to_dict(self) -> dict:
        d = {"spp": self.spp, "sampler": self.sampler, "samples_per_pass": self.samples_per_pass,
             "edge_spp": self.edge_spp}
        if self.checkerboard_spp:
            d["checkerboard_spp"] = self.checkerboard_spp
        if self.edge_mode != "path":  # absent by default: the shipped specs' identities are unchanged
            d["edge_mode"] = self.edge_mode
        if self.board_mode != "path":
            d["board_mode"] = self.board_mode
        if "frame" in (self.edge_mode, self.board_mode):
            d["shading_step_px"] = self.shading_step_px
        if self.exposure_s:
            d["exposure_s"] = self.exposure_s
        return d


def _rect_local(half_x: float, half_y: float, z_m: float) -> np.ndarray:
    """Local transform of Mitsuba's [-1,1]² rectangle/unit disk, facing the camera (normal = -z local)."""
    m = np.diag([half_x, -half_y, -1.0, 1.0])  # flip y and z: det > 0 and the normal points to the camera
    m[2, 3] = z_m
    return m


def _look_at(origin: np.ndarray, target: np.ndarray, up=(0.0, -1.0, 0.0)) -> np.ndarray:
    """4×4 transform taking local +z to the direction origin -> target (Mitsuba's look_at)."""
    d = target - origin
    d = d / np.linalg.norm(d)
    left = np.cross(np.asarray(up, float), d)
    left /= np.linalg.norm(left)
    new_up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, origin
    return m


def light_radiance_for(irradiance_w_m2: float, pose: Pose, light_pos: np.ndarray) -> float:
    """Radiance of the square light giving ``irradiance_w_m2`` at the board centre (small-source formula)."""
    c = pose.translation_m
    to_light = light_pos - c
    r = np.linalg.norm(to_light)
    board_normal = -pose.rotation[:, 2]  # towards the camera
    cos_b = max(float(np.dot(board_normal, to_light / r)), 1e-3)
    area = (2 * LIGHT_HALF_SIZE_M) ** 2
    return float(irradiance_w_m2 * r * r / (area * cos_b))  # the light faces the centre: cos_l = 1


class _Rig:
    """Common part: one loaded scene, one camera, parameter updates."""

    #: ``mi.load_dict``'s optimize: merge equal nodes and the meshes that share a BSDF (see ``SceneRig``)
    _load_optimize = True

    def __init__(self, camera: Camera, settings: RenderSettings, crop=None, window=None):
        import mitsuba as mi

        self.mi = mi
        self.camera = camera
        self.settings = settings
        self.crop = crop
        self.window = window
        self._psf = None
        sampler = {"type": settings.sampler, "sample_count": settings.spp}
        integrator = {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0}
        if settings.samples_per_pass:
            integrator["samples_per_pass"] = settings.samples_per_pass
        self.scene_dict = {"type": "scene", "integrator": integrator,
                           "sensor": sensor_dict(camera, sampler, crop, exposure_s=settings.exposure_s,
                                                 window=window)}
        self.scene_dict.update(self._shapes())
        # ``optimize`` is passed only when off: older Mitsuba 3 releases lack the argument (and never merge)
        self.scene = mi.load_dict(self.scene_dict) if self._load_optimize else mi.load_dict(self.scene_dict,
                                                                                            optimize=False)
        self.params = mi.traverse(self.scene)
        self.sensor = self.scene.sensors()[0]  # the Python LensSensor (``set_window``)
        self._last: dict = {}  # the transform last set per parameter key

    def psf_description(self) -> dict | None:
        """How the sensor samples the lens PSF (None: the pixel box alone)."""
        from edgetruth.render.optics.psf import psf_params, psf_table

        if self._psf is None:
            table = psf_table(psf_params(self.camera))
            self._psf = {"sampled": False, "why": "no PSF, or one within 1e-4 of an ideal OTF up to Nyquist"} \
                if table is None else {"sampled": True, **table.describe()}
        return self._psf

    def _T(self, m: np.ndarray):
        return self.mi.ScalarTransform4f(np.asarray(m, dtype=np.float64).tolist())

    def _set_transform(self, key: str, m: np.ndarray) -> None:
        # opaque: a literal transform is baked into the kernel (the area light's is, inside the
        # emitter's sample_direction), so every new pose would cost an LLVM compile (~80 ms) and
        # 20 KB of kernel cache on disk; opaque, one kernel serves every pose
        import drjit as dr

        m = np.asarray(m, dtype=np.float64)
        last = self._last.get(key)
        if last is not None and np.array_equal(last, m):
            return  # e.g. a parked target: no update, no rebuild
        self._last[key] = m.copy()
        t = self.mi.Transform4f(m.tolist())
        dr.make_opaque(t)
        self.params[key] = t

    def _set_light(self, pose: Pose, irradiance_w_m2: float, position_m=None) -> float:
        pos = LIGHT_OFFSET_M if position_m is None else np.asarray(position_m, dtype=np.float64)
        self._light_pos = pos
        m = _look_at(pos, pose.translation_m) @ np.diag([LIGHT_HALF_SIZE_M, LIGHT_HALF_SIZE_M, 1.0, 1.0])
        self._set_transform("light.to_world", m)
        le = light_radiance_for(irradiance_w_m2, pose, pos)
        self.params["light.emitter.radiance.value"] = le
        return le

    def _light_dict(self) -> dict:
        return {"type": "rectangle", "to_world": self._T(np.eye(4)),
                "emitter": {"type": "area", "radiance": {"type": "uniform", "value": 1.0}}}

    def render(self, seed: int, window_at: tuple[int, int] | None = None, pixels=None) -> np.ndarray:
        """Render with the current parameters; radiance (H, W) float32 (RGB channels are equal).
        ``window_at``: where a window rig's film sits in the frame (its top-left pixel); ``pixels``:
        (xs, ys), the frame pixel of each of its film pixels in row-major order (``set_pixels``)."""
        if pixels is not None:
            self.sensor.set_pixels(*pixels)
        elif window_at is not None:
            self.sensor.set_window(*window_at)

        def once(pass_seed: int, spp: int) -> np.ndarray:  # pass_seed: 31-bit already (render_in_passes)
            img = self.mi.render(self.scene, self.params, seed=pass_seed, spp=spp)
            return np.asarray(img, dtype=np.float32)[..., 1].copy()  # achromatic scene: R = G = B exactly

        # passes on a GPU: its film's atomic adds would otherwise differ run to run (sample_passes)
        return render_in_passes(once, int(seed) & 0x7FFFFFFF, self.settings.spp, self.mi.variant(),
                                self.settings.sampler)

    def light_ground_truth(self, pose: Pose, le: float, irradiance_w_m2: float) -> dict:
        pos = getattr(self, "_light_pos", LIGHT_OFFSET_M)
        return {"type": "square area light", "side_m": 2 * LIGHT_HALF_SIZE_M,
                "position_m": np.asarray(pos, dtype=np.float64).tolist(), "aimed_at": "board centre",
                "radiance_w_m2_sr": le, "board_centre_irradiance_w_m2": irradiance_w_m2}


class TargetRig(_Rig):
    """The target scene."""

    def __init__(self, camera: Camera, settings: RenderSettings, target_size_m: float = 0.13, crop=None,
                 window=None):
        self.target_size_m = float(target_size_m)
        self._scene_rigs: dict = {}  # TargetScene -> SceneRig
        self._active = None
        super().__init__(camera, settings, crop, window)

    def _shapes(self) -> dict:
        T = self._T(_PARKED)
        return {
            "light": self._light_dict(),
            "board": {"type": "rectangle", "to_world": self._T(_rect_local(*BOARD_HALF_SIZE_M, 0.0)),
                      "bsdf": {"type": "diffuse", "reflectance": BOARD_REFLECTANCE}},
            "square_black": {"type": "rectangle", "to_world": T,
                             "bsdf": {"type": "diffuse", "reflectance": TARGETS["T1"]["reflectance"]}},
            "disk_black": {"type": "disk", "to_world": T,
                           "bsdf": {"type": "diffuse", "reflectance": TARGETS["T2"]["reflectance"]}},
            "square_gray": {"type": "rectangle", "to_world": T,
                            "bsdf": {"type": "diffuse", "reflectance": TARGETS["T3"]["reflectance"]}},
            "square_glossy": {"type": "rectangle", "to_world": T,
                              "bsdf": {"type": "roughplastic", "distribution": "ggx",
                                       "alpha": TARGETS["T4"]["alpha"], "int_ior": TARGETS["T4"]["eta"],
                                       "diffuse_reflectance": TARGETS["T4"]["reflectance"]}},
        }

    def set_state(self, target, pose: Pose, irradiance_w_m2: float, light_position_m=None) -> float:
        """Place ``target`` at ``pose``; returns the (first) light's radiance.  ``target``: a preset id
        (T1..T4: this rig's fixed scene) or a ``TargetScene`` (its own ``SceneRig``, loaded on first use
        with this rig's camera, settings, crop and window, and rendered until the next ``set_state``)."""
        from edgetruth.render.scene.target_scene import TargetScene

        if isinstance(target, TargetScene):
            if target not in self._scene_rigs:
                self._scene_rigs[target] = SceneRig(self.camera, self.settings, target, self.crop, self.window)
            self._active = self._scene_rigs[target]
            return self._active.set_state(target, pose, irradiance_w_m2)
        self._active = None
        board = pose.matrix @ _rect_local(*BOARD_HALF_SIZE_M, 0.0)
        self._set_transform("board.to_world", board)
        half = self.target_size_m / 2
        active = _SHAPE_KEY[target]
        for key in _SHAPE_KEY.values():
            m = pose.matrix @ _rect_local(half, half, -TARGET_STANDOFF_M) if key == active else _PARKED
            self._set_transform(f"{key}.to_world", m)
        le = self._set_light(pose, irradiance_w_m2, light_position_m)
        self.params.update()
        return le

    def render(self, seed: int, window_at: tuple[int, int] | None = None, pixels=None) -> np.ndarray:
        if getattr(self, "_active", None) is not None:
            return self._active.render(seed, window_at, pixels)
        return super().render(seed, window_at, pixels)

    def light_ground_truth(self, pose: Pose, le: float, irradiance_w_m2: float) -> dict:
        if getattr(self, "_active", None) is not None:
            return self._active.light_ground_truth(pose, le, irradiance_w_m2)
        return super().light_ground_truth(pose, le, irradiance_w_m2)


def _shape_local(cx: float, cy: float, a: float, b: float, theta_rad: float, z_m: float) -> np.ndarray:
    """Local transform of Mitsuba's [-1,1]² rectangle / unit disk to a board rectangle or ellipse of half
    sizes (a, b) turned by theta about the board normal, centred at (cx, cy), facing the camera (as
    ``_rect_local``: y and z flipped, det > 0, the normal towards the camera)."""
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    m = np.eye(4)
    m[:2, :2] = np.array([[c, -s], [s, c]]) @ np.diag([a, -b])
    m[2, 2] = -1.0
    m[:3, 3] = (cx, cy, z_m)
    return m


def _board_uv(cx: float, cy: float, a: float, b: float, theta_rad: float, half_size_m=BOARD_HALF_SIZE_M) -> tuple:
    """The board texture's (u0, ux, uy, v0, vx, vy) on a disk of ``_shape_local(cx, cy, a, b, theta)`` (a
    ring's hole, which shows the board): the board point of local (x, y) is R(theta) (a x, -b y) + (cx, cy),
    the board's image spans it from (-hx, -hy) (top-left) to (hx, hy) (``half_size_m``)."""
    hx, hy = half_size_m
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    return ((cx + hx) / (2 * hx), c * a / (2 * hx), s * b / (2 * hx),
            (hy - cy) / (2 * hy), -s * a / (2 * hy), c * b / (2 * hy))


def _make_mesh(mi, name: str, verts: np.ndarray, faces: np.ndarray, bsdf: dict, texcoords=None):
    """A triangle mesh with its own BSDF (without one a mesh gets Mitsuba's default diffuse 0.5) and,
    optionally, per-vertex texture coordinates (N, 2)."""
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    mesh = mi.Mesh(name, vertex_count=len(verts), face_count=len(faces), has_vertex_normals=False,
                   has_vertex_texcoords=texcoords is not None, props=props)
    params = mi.traverse(mesh)
    vtype = type(params["vertex_positions"])  # mi.Float on JIT, drjit.scalar.ArrayXf on scalar
    params["vertex_positions"] = vtype(np.asarray(verts, np.float32).ravel())
    params["faces"] = type(params["faces"])(np.asarray(faces, np.uint32).ravel())
    if texcoords is not None:
        params["vertex_texcoords"] = vtype(np.asarray(texcoords, np.float32).ravel())
    params.update()
    return mesh, vtype


class SceneRig(_Rig):
    """The target scene of a ``TargetScene``: the board, the catalogue's shapes (rectangles as Mitsuba
    rectangles, conics as affinely mapped disks -- both exact --, polygons as triangle meshes, a ring as
    its outer disk with a disk of the board's material on its hole), each with its own material, shape k
    ``(k + 1) x TARGET_STANDOFF_M`` in front of the board; clutter (raised shapes, boxes as meshes of their
    top and sides); its lights and an optional constant ambient emitter.  A printed texture fills each
    shape's bounding box (``Shape.texture_frame``): a rectangle's own uv, a grid square's ``to_uv``, a
    polygon's vertex texture coordinates, a disk's polar uv through ``materials.polar_print_plugin``.
    Materials and the set of lights are fixed per loaded scene; poses and powers are updated."""

    #: no merging: the loader would fuse shapes of one material (two rectangles, a grid's squares) into one
    #: mesh, whose per-shape ``to_world`` keys ``set_state`` needs would then be gone
    _load_optimize = False

    def __init__(self, camera: Camera, settings: RenderSettings, scene, crop=None, window=None):
        self.target_scene = scene
        super().__init__(camera, settings, crop, window)

    def _shapes(self) -> dict:
        from edgetruth.render.scene.polygons import triangulate

        sc = self.target_scene
        T = self._T(np.eye(4))
        d: dict = {}
        for i, lt in enumerate(sc.lights):
            # distinct placeholder values: the loader merges equal dicts into one object, whose value
            # ``traverse`` would then list (and ``set_state`` set) under one key only; above 1, so that no
            # material's uniform value (all in [0, 1], e.g. a conductor's specular_reflectance) equals them
            unit = {"type": "uniform", "value": 1000.0 + i}
            if lt.type == "area":
                d[f"light{i}"] = {"type": "rectangle", "to_world": T, "emitter": {"type": "area", "radiance": unit}}
            elif lt.type == "point":
                d[f"light{i}"] = {"type": "point", "position": [0.0, 0.0, -1.0], "intensity": unit}
            else:
                d[f"light{i}"] = {"type": "spot", "to_world": T, "intensity": unit, "cutoff_angle": lt.cutoff_deg,
                                  "beam_width": lt.beam_deg}
        if sc.ambient > 0:
            d["ambient"] = {"type": "constant", "radiance": {"type": "uniform", "value": 999.5}}  # as above
        d["board"] = {"type": "rectangle", "to_world": self._T(_rect_local(*sc.board_half_size_m, 0.0)),
                      "bsdf": sc.board.to_bsdf()}
        self._locals, self._meshes = {}, {}
        items = [(f"shape{k}", shape, -(k + 1) * TARGET_STANDOFF_M) for k, shape in enumerate(sc.shapes)]
        items += [(f"clutter{c}", item.shape, -item.raised_m) for c, item in enumerate(sc.clutter)]
        for key, shape, z in items:
            if shape.type == "box":  # a closed solid but its base: a mesh of its top and sides
                verts = shape.corners()
                mesh, vtype = _make_mesh(self.mi, key, verts, shape.faces(), shape.material.to_bsdf())
                self._meshes[key] = (verts, vtype)
                d[key] = mesh
                continue
            outs = shape.outlines()
            o = outs[0]
            printed = bool(shape.material.texture)
            if shape.type == "grid":  # each element a Mitsuba rectangle or disk: exact, like the single shapes
                h = shape.element_size_m / 2
                for e, (oe, (lx, ly)) in enumerate(zip(outs, shape.grid_centres_local())):
                    ex, ey = oe.conic[:2] if oe.kind == "ellipse" else np.mean(np.asarray(oe.vertices), axis=0)
                    self._locals[f"{key}_{e}"] = _shape_local(ex, ey, h, h, np.radians(shape.rotation_deg), z)
                    uv = (("rect" if oe.kind == "polygon" else "polar"), shape.texture_uv(lx, ly, h, h)) \
                        if printed else None  # each element shows its part of the grid's image
                    d[f"{key}_{e}"] = {"type": "rectangle" if oe.kind == "polygon" else "disk", "to_world": T,
                                          "bsdf": shape.material.to_bsdf(uv)}
            elif o.kind == "ellipse":
                cx, cy, a, b, th = o.conic
                self._locals[key] = _shape_local(cx, cy, a, b, th, z)
                uv = ("polar", shape.texture_uv(0.0, 0.0, a, b)) if printed else None
                d[key] = {"type": "disk", "to_world": T, "bsdf": shape.material.to_bsdf(uv)}
                if shape.type == "ring":  # the hole: the board's material, half a stand-off in front
                    cx, cy, a, b, th = outs[1].conic
                    self._locals[f"{key}_hole"] = _shape_local(cx, cy, a, b, th, z - 0.5 * TARGET_STANDOFF_M)
                    d[f"{key}_hole"] = {"type": "disk", "to_world": T, "bsdf": sc.board.to_bsdf(
                        ("polar", _board_uv(cx, cy, a, b, th, sc.board_half_size_m)) if sc.board.texture else None)}
            elif shape.type == "checkerboard":  # the dark squares as one mesh, wound as CheckerRig's
                q = np.asarray([oe.vertices for oe in outs], float)  # (n, 4, 2) TL, TR, BR, BL
                n = len(q)
                verts = np.column_stack([q.reshape(-1, 2), np.full(4 * n, z)])
                k4 = 4 * np.arange(n)
                tris = np.concatenate([np.stack([k4, k4 + 2, k4 + 1], 1), np.stack([k4, k4 + 3, k4 + 2], 1)])
                uv = None
                if printed:  # the print spans the whole board of squares (texture_frame); exact: affine
                    x0, y0, x1, y1 = shape.texture_frame()
                    ql = shape.checker_quads_local().reshape(-1, 2)
                    uv = np.column_stack([(ql[:, 0] - x0) / (x1 - x0), (y1 - ql[:, 1]) / (y1 - y0)])
                bsdf = shape.material.to_bsdf(("rect", (0.5, 0.5, 0.0, 0.5, 0.0, 0.5)) if printed else None)
                mesh, vtype = _make_mesh(self.mi, key, verts, tris, bsdf, texcoords=uv)
                self._meshes[key] = (verts, vtype)
                d[key] = mesh
            elif shape.type == "rectangle":
                w, h = shape.width_m / 2, shape.height_m / 2
                self._locals[key] = _shape_local(*shape.offset_m, w, h, np.radians(shape.rotation_deg), z)
                d[key] = {"type": "rectangle", "to_world": T, "bsdf": shape.material.to_bsdf()}
            else:
                v = np.asarray(o.vertices, float)
                tris = triangulate(v)[:, ::-1]  # reversed: the face normal points to the camera (as the checker)
                verts = np.column_stack([v, np.full(len(v), z)])
                uv = None
                if printed:  # texture coordinates of the vertices in the polygon's bounding box (exact: affine)
                    x0, y0, x1, y1 = shape.texture_frame()
                    vm = np.asarray(shape.vertices_m, float)
                    uv = np.column_stack([(vm[:, 0] - x0) / (x1 - x0), (y1 - vm[:, 1]) / (y1 - y0)])
                bsdf = shape.material.to_bsdf(("rect", (0.5, 0.5, 0.0, 0.5, 0.0, 0.5)) if printed else None)  # own uv
                mesh, vtype = _make_mesh(self.mi, key, verts, tris, bsdf, texcoords=uv)
                self._meshes[key] = (verts, vtype)
                d[key] = mesh
        return d

    def set_state(self, scene, pose: Pose, irradiance_w_m2: float, light_position_m=None) -> float:
        self._set_transform("board.to_world", pose.matrix @ _rect_local(*self.target_scene.board_half_size_m, 0.0))
        for key, m in self._locals.items():
            self._set_transform(f"{key}.to_world", pose.matrix @ m)
        for key, (verts, vtype) in self._meshes.items():
            self.params[f"{key}.vertex_positions"] = vtype(pose.to_camera(verts).astype(np.float32).ravel())
        first = None
        for i, lt in enumerate(self.target_scene.lights):
            e = lt.emission_for(irradiance_w_m2, pose)
            first = e if first is None else first
            if lt.type == "point":
                key = f"light{i}.position"
                self.params[key] = type(self.params[key])(*[float(c) for c in lt.position_m])
                self.params[f"light{i}.intensity.value"] = e
            else:
                self._set_transform(f"light{i}.to_world", lt.to_world(pose))
                self.params[f"light{i}.emitter.radiance.value" if lt.type == "area"
                            else f"light{i}.intensity.value"] = e
        if self.target_scene.ambient > 0:  # a uniform sky of radiance L gives pi L on the open board
            self.params["ambient.radiance.value"] = self.target_scene.ambient * irradiance_w_m2 / np.pi
        self.params.update()
        return float(first)

    def light_ground_truth(self, pose: Pose, le: float, irradiance_w_m2: float) -> dict:
        sc = self.target_scene
        centres = [pose.to_camera(np.array([[0.0, 0.0, 0.0]]))[0]] + [
            pose.to_camera(np.array([[*s.offset_m, -(k + 1) * TARGET_STANDOFF_M]]))[0] for k, s in enumerate(sc.shapes)]
        pts = np.asarray(centres)
        lights, total = [], np.zeros(len(pts))
        for lt in sc.lights:
            e = lt.irradiance_at(irradiance_w_m2, pose, pts)
            total += e
            lights.append({**lt.to_dict(), "position_m": list(lt.position_m),
                           "aim_point_camera_m": lt.aim_point(pose).tolist(),
                           ("radiance_w_m2_sr" if lt.type == "area" else "intensity_w_sr"):
                               lt.emission_for(irradiance_w_m2, pose),
                           "irradiance_board_centre_w_m2": float(e[0]),
                           "irradiance_shape_centres_w_m2": e[1:].tolist()})
        amb = sc.ambient * irradiance_w_m2
        # across the target (shape 0's outline): the illumination's non-uniformity there
        xy = sc.primary.sample_points(64)
        edge = pose.to_camera(np.column_stack([xy, np.full(len(xy), -TARGET_STANDOFF_M)]))
        e_edge = sum(lt.irradiance_at(irradiance_w_m2, pose, edge) for lt in sc.lights) + amb
        out = {"type": "lights", "lights": lights,
               "board_centre_irradiance_w_m2": float(total[0] + amb),
               "shape_centre_irradiance_w_m2": (total[1:] + amb).tolist(),
               "target_outline_irradiance_w_m2": {"min": float(np.min(e_edge)), "max": float(np.max(e_edge)),
                                                  "nonuniformity_pct": float(100.0 * (np.max(e_edge) - np.min(e_edge))
                                                                             / np.mean(e_edge))},
               "meaning": "irradiance (W/m^2) on the board plane at the board centre and at each shape's centre "
                          "from every light (exact: area lights integrated over their square; nothing on the flat "
                          "board shadows them); each light gives share x irradiance_w_m2 at its aim point; "
                          "target_outline_irradiance_w_m2: the range on shape 0's outline, its non-uniformity "
                          "100 (max - min) / mean"}
        if sc.clutter:  # the irradiance above ignores them: where they shade the board is clutter[].shadows
            out["meaning"] += "; clutter is not counted (its shadows: the truth's clutter[].shadows)"
        if sc.ambient > 0:
            out["ambient"] = {"type": "constant environment", "radiance_w_m2_sr": amb / np.pi,
                              "irradiance_w_m2": amb, "share": sc.ambient}
        return out


class CheckerRig(_Rig):
    """The checkerboard scene: black squares as one triangle mesh on a white plate.  ``board``: a
    ``Checkerboard`` or a ``SquareBoard`` (anything with ``black_quads_local``, ``half_size_m`` and,
    optionally, ``square_reflectance`` and ``board_reflectance``)."""

    def __init__(self, camera: Camera, settings: RenderSettings, board: Checkerboard = Checkerboard(), crop=None,
                 window=None, bent: bool = False):
        self.board = board
        #: plate and squares as fine meshes whose heights ``set_state`` sets (``render.scene.bend``); a flat
        #: rig keeps Mitsuba's exact rectangle and one quad a square (its renders stay byte-identical)
        self.bent = bent
        super().__init__(camera, settings, crop, window)

    def _mesh(self):
        mi = self.mi
        quads = self.board.black_quads_local(-TARGET_STANDOFF_M)
        n = len(quads)
        verts = quads.reshape(-1, 3)
        # wound so that the face normal points to the camera (local -z): a one-sided diffuse BSDF seen
        # from behind is black whatever its albedo
        faces = np.concatenate([np.stack([4 * np.arange(n), 4 * np.arange(n) + 2, 4 * np.arange(n) + 1], 1),
                                np.stack([4 * np.arange(n), 4 * np.arange(n) + 3, 4 * np.arange(n) + 2], 1)])
        props = mi.Properties()
        # without a BSDF of its own a mesh gets Mitsuba's default diffuse 0.5
        props["bsdf"] = mi.load_dict({"type": "diffuse", "reflectance": float(
            getattr(self.board, "square_reflectance", CHECKER_BLACK_REFLECTANCE))})
        mesh = mi.Mesh("checker", vertex_count=len(verts), face_count=len(faces), has_vertex_normals=False,
                       has_vertex_texcoords=False, props=props)
        params = mi.traverse(mesh)
        # buffer types differ per variant (mi.Float on JIT, drjit.scalar.ArrayXf on scalar)
        self._vertex_type = type(params["vertex_positions"])
        params["vertex_positions"] = self._vertex_type(verts.astype(np.float32).ravel())
        params["faces"] = type(params["faces"])(faces.astype(np.uint32).ravel())
        params.update()
        self._verts_local = verts
        return mesh

    def _bent_shapes(self, plate_bsdf: dict) -> dict:
        from edgetruth.render.scene.bend import grid_mesh

        mi = self.mi
        self._plate_verts, self._plate_faces = grid_mesh(self.board.plate_corners_local()[None])
        plate, _ = _make_mesh(mi, "plate", self._plate_verts, self._plate_faces, plate_bsdf)
        self._verts_local, self._faces = grid_mesh(self.board.black_quads_local(-TARGET_STANDOFF_M))
        checker, self._vertex_type = _make_mesh(mi, "checker", self._verts_local, self._faces, {
            "type": "diffuse", "reflectance": float(getattr(self.board, "square_reflectance",
                                                            CHECKER_BLACK_REFLECTANCE))})
        return {"light": self._light_dict(), "plate": plate, "checker": checker}

    def _shapes(self) -> dict:
        half_x, half_y = self.board.half_size_m
        self._plate_local = _rect_local(half_x, half_y, 0.0)
        plate_bsdf = {"type": "diffuse", "reflectance": float(getattr(self.board, "board_reflectance",
                                                                      BOARD_REFLECTANCE))}
        if self.bent:
            return self._bent_shapes(plate_bsdf)
        mesh = self._mesh()
        return {
            "light": self._light_dict(),
            "plate": {"type": "rectangle", "to_world": self._T(self._plate_local), "bsdf": plate_bsdf},
            "checker": mesh,
        }

    def mesh_sag_m(self, bend) -> float:
        """The bent rig's largest chord sag under ``bend`` (m; ``render.scene.bend.check_sag``)."""
        from edgetruth.render.scene.bend import check_sag

        return max(check_sag(bend, self._plate_verts, self._plate_faces, "the plate"),
                   check_sag(bend, self._verts_local, self._faces, "the squares"))

    def set_plate_half_size(self, pose: Pose, half_size_m) -> None:
        """Make a flat rig's plate (posed at ``pose``) ``half_size_m`` = (hx, hy) m, centred as the board's: the shading
        rig of ``board_frame`` enlarges it beyond the view."""
        if self.bent:
            raise ValueError("a bent CheckerRig's plate is a mesh of the board's own size")
        self._set_transform("plate.to_world", pose.matrix @ _rect_local(float(half_size_m[0]), float(half_size_m[1]),
                                                                        0.0))
        self.params.update()

    def set_state(self, pose: Pose, irradiance_w_m2: float, light_position_m=None, bend=None) -> float:
        """Pose the board (and, on a bent rig, curl it by ``bend``, a ``render.scene.bend.BoardBend``;
        None: flat) and set the light; the light's radiance."""
        if self.bent:
            def place(v):
                return pose.to_camera(v if bend is None else bend.lift(v)).astype(np.float32).ravel()

            self.params["plate.vertex_positions"] = self._vertex_type(place(self._plate_verts))
            self.params["checker.vertex_positions"] = self._vertex_type(place(self._verts_local))
        else:
            if bend is not None:
                raise ValueError("a flat CheckerRig cannot bend: make it with bent=True")
            self._set_transform("plate.to_world", pose.matrix @ self._plate_local)
            self.params["checker.vertex_positions"] = self._vertex_type(
                pose.to_camera(self._verts_local).astype(np.float32).ravel())
        le = self._set_light(pose, irradiance_w_m2, light_position_m)
        self.params.update()
        return le
