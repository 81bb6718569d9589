"""Lights of the target scene: square area lights, point and spot lights, and a constant ambient term.

Pure data and geometry (no Mitsuba).  A light's power is stated as the irradiance it gives at its aim
point on the board (``share`` x the group's ``irradiance_w_m2``), so a design's power levels and the
radiance units (which scale a render by irradiance) keep their meaning with any set of lights.  Each
image's ground truth records every light with its emission and the irradiance it gives at the board
centre and at every shape's centre (``irradiance_at``; nothing on the flat board can shadow it).
``unit_irradiance_occluded`` gives an area light's exact irradiance where planar clutter hides part of it
(Lambert's contour formula for the visible part of its square).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.schema import Key, parse_table

LIGHT_TYPES = ("area", "point", "spot")
DEFAULT_LIGHT_POSITION_M = (0.0, -0.15, -0.05)  # above the camera, behind its image plane
DEFAULT_AREA_SIDE_M = 0.05
#: midpoint rule over the area light: 24 x 24 cells (the 1/r^2 cos cos integrand varies by < 1e-4 across
#: a 5 cm light at 0.5 m, so the quadrature is exact to ~1e-9 relative)
AREA_QUADRATURE = 24


def look_at(origin: np.ndarray, target: np.ndarray, up=(0.0, -1.0, 0.0)) -> np.ndarray:
    """4x4 transform taking local +z to the direction origin -> target (Mitsuba's look_at)."""
    d = np.asarray(target, float) - np.asarray(origin, float)
    d = d / np.linalg.norm(d)
    left = np.cross(np.asarray(up, float), d)
    if np.linalg.norm(left) < 1e-9:  # looking straight along up
        left = np.cross(np.array([1.0, 0.0, 0.0]), d)
    left /= np.linalg.norm(left)
    new_up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, origin
    return m


@dataclass(frozen=True)
class Light:
    """One light: ``position_m`` in the camera frame, aimed at ``aim_board_m`` (x, y on the board, board
    frame), giving ``share`` x the group's irradiance there."""

    type: str = "area"
    position_m: tuple = DEFAULT_LIGHT_POSITION_M
    aim_board_m: tuple = (0.0, 0.0)
    size_m: float = DEFAULT_AREA_SIDE_M
    share: float = 1.0
    cutoff_deg: float = 20.0
    beam_deg: float = 15.0

    # --- geometry -------------------------------------------------------------------------
    def aim_point(self, pose) -> np.ndarray:
        return pose.to_camera(np.array([[self.aim_board_m[0], self.aim_board_m[1], 0.0]]))[0]

    def to_world(self, pose) -> np.ndarray:
        """The emitter's transform (area: the square's, scaled to its half side; spot: its frame)."""
        m = look_at(np.asarray(self.position_m, float), self.aim_point(pose))
        if self.type == "area":
            m = m @ np.diag([self.size_m / 2, self.size_m / 2, 1.0, 1.0])
        return m

    def _unit_irradiance(self, pose, points_cam: np.ndarray) -> np.ndarray:
        """Irradiance (W/m^2) at board points per unit emission (radiance for area, intensity else)."""
        p = np.atleast_2d(np.asarray(points_cam, float))
        n_b = -pose.rotation[:, 2]  # the board's normal, towards the camera
        pos = np.asarray(self.position_m, float)
        if self.type == "area":
            m = self.to_world(pose)
            u = (np.arange(AREA_QUADRATURE) + 0.5) / AREA_QUADRATURE * 2 - 1
            gu, gv = np.meshgrid(u, u)
            src = np.column_stack([gu.ravel(), gv.ravel(), np.zeros(gu.size), np.ones(gu.size)]) @ m.T
            src = src[:, :3]
            n_l = m[:3, 2] / np.linalg.norm(m[:3, 2])
            da = self.size_m ** 2 / gu.size
            d = src[None, :, :] - p[:, None, :]  # point -> light element
            r2 = np.sum(d * d, axis=2)
            r = np.sqrt(r2)
            cos_b = np.clip(d @ n_b / r, 0.0, None)
            cos_l = np.clip(-(d @ n_l) / r, 0.0, None)
            return np.sum(cos_b * cos_l / r2, axis=1) * da
        d = pos[None, :] - p
        r2 = np.sum(d * d, axis=1)
        r = np.sqrt(r2)
        cos_b = np.clip(d @ n_b / r, 0.0, None)
        e = cos_b / r2
        if self.type == "spot":  # Mitsuba's spot: 1 inside the beam, linear in angle to 0 at the cutoff
            axis = self.aim_point(pose) - pos
            axis /= np.linalg.norm(axis)
            theta = np.arccos(np.clip(-(d / r[:, None]) @ axis, -1.0, 1.0))
            cut, beam = math.radians(self.cutoff_deg), math.radians(self.beam_deg)
            fall = np.where(theta <= beam, 1.0, np.clip((cut - theta) / (cut - beam), 0.0, 1.0))
            e = e * np.where(theta < cut, fall, 0.0)
        return e

    def emission_for(self, irradiance_w_m2: float, pose) -> float:
        """Radiance (area, W/m^2/sr) or intensity (point, spot, W/sr) giving ``share x irradiance_w_m2`` at
        the aim point."""
        unit = float(self._unit_irradiance(pose, self.aim_point(pose)[None])[0])
        if unit <= 0:
            raise InputError(f"a {self.type} light at {list(self.position_m)} m does not light its aim point "
                             f"{list(self.aim_board_m)} m (it is behind the board); move it in front of the board")
        return self.share * float(irradiance_w_m2) / unit

    def irradiance_at(self, irradiance_w_m2: float, pose, points_cam: np.ndarray) -> np.ndarray:
        return self.emission_for(irradiance_w_m2, pose) * self._unit_irradiance(pose, points_cam)

    def to_dict(self) -> dict:
        d = {"type": self.type, "position_m": list(self.position_m), "aim_board_m": list(self.aim_board_m),
             "share": self.share}
        if self.type == "area":
            d["side_m"] = self.size_m
        if self.type == "spot":
            d.update(cutoff_deg=self.cutoff_deg, beam_deg=self.beam_deg)
        return d


_L = Light()


def _behind(v) -> str | None:
    return None if v[2] < 0 else ("z must be < 0 (behind the camera's image plane), or the light could stand "
                                  "in view or shade the board")


LIGHT_KEYS = [
    Key("type", "str", _L.type, "", "area: a square emitter facing its aim point; point; spot (a cone: full "
        "inside beam_deg, falling linearly in angle to 0 at cutoff_deg)", choices=LIGHT_TYPES),
    Key("position_m", "vec3", _L.position_m, "m", "where the light sits (camera frame: x right, y down, z "
        "forward); z < 0", -100.0, 100.0, check=_behind),
    Key("aim_board_m", "vec2", _L.aim_board_m, "m", "the board point the light aims at (board frame: x right, "
        "y down from the board centre); its power is stated there", -100.0, 100.0),
    Key("size_m", "float", _L.size_m, "m", "side of an area light (larger: softer, more Monte-Carlo noise)",
        1e-4, 10.0),
    Key("share", "float", _L.share, "", "power: irradiance at the aim point as a multiple of the group's "
        "irradiance_w_m2", 0.0, 1e3),
    Key("cutoff_deg", "float", _L.cutoff_deg, "deg", "spot: half-angle of the cone's edge", 0.1, 89.0),
    Key("beam_deg", "float", _L.beam_deg, "deg", "spot: half-angle of the fully lit core (< cutoff_deg)", 0.0,
        89.0),
]


def lights_from_list(items: list, where: str) -> tuple:
    """``lights = [{...}, ...]`` -> a tuple of ``Light``, each checked."""
    out = []
    for i, d in enumerate(items):
        w = f"{where}[{i}]"
        v = parse_table(d, LIGHT_KEYS, w)
        own = {"area": ("size_m",), "point": (), "spot": ("cutoff_deg", "beam_deg")}[v["type"]]
        wrong = sorted(k for k in ("size_m", "cutoff_deg", "beam_deg") if k in d and k not in own)
        if wrong:
            raise InputError(f"{w}: {', '.join(wrong)} does not apply to a {v['type']} light; remove it")
        if v["type"] == "spot" and v["beam_deg"] >= v["cutoff_deg"]:
            raise InputError(f"{w}: beam_deg = {v['beam_deg']:g} >= cutoff_deg = {v['cutoff_deg']:g}; make the "
                             "fully lit core narrower than the cone")
        out.append(Light(**v))
    return tuple(out)


# --- exact area-light shadows of planar occluders -------------------------------------------------------
def lambert_sum(a: np.ndarray, b: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Lambert's contour sum over segments a -> b (..., S, 3), given relative to the lit point: sum of
    theta (n . (a x b) / |a x b|), theta the angle the segment subtends.  For a closed polygon of uniform
    radiance L the irradiance is L / 2 x |sum| (the projected solid angle; exact).  Zero-length segments
    add nothing."""
    c = np.cross(a, b)
    cn = np.linalg.norm(c, axis=-1)
    theta = np.arctan2(cn, np.sum(a * b, axis=-1))
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(cn > 0, theta * (c @ normal) / cn, 0.0)
    return np.sum(t, axis=-1)


def _clip_segments(p0: np.ndarray, p1: np.ndarray, q: np.ndarray):
    """Clip segments p0 -> p1 (..., S, 2) to the convex polygon q (..., m, 2), counter-clockwise (x right,
    y up sense: cross > 0 inside); returns the clipped ends (..., S, 2) and whether anything is left."""
    e = np.roll(q, -1, axis=-2) - q  # (..., m, 2)
    lo = np.zeros(p0.shape[:-1])
    hi = np.ones(p0.shape[:-1])

    def side(p):  # (..., S, m): cross(e, p - q) > 0 inside
        d = p[..., :, None, :] - q[..., None, :, :]
        return e[..., None, :, 0] * d[..., 1] - e[..., None, :, 1] * d[..., 0]

    f0, f1 = side(p0), side(p1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = f0 / (f0 - f1)
    enter = (f0 < 0) & (f1 >= 0)
    leave = (f0 >= 0) & (f1 < 0)
    outside = (f0 < 0) & (f1 < 0)
    lo = np.max(np.where(enter, t, 0.0), axis=-1)
    hi = np.min(np.where(leave, t, 1.0), axis=-1)
    ok = (hi > lo) & ~np.any(outside, axis=-1)
    d = p1 - p0
    return p0 + lo[..., None] * d, p0 + hi[..., None] * d, ok


def _ccw(poly: np.ndarray) -> np.ndarray:
    """The polygons (..., n, 2) ordered counter-clockwise (positive shoelace area)."""
    x, y = poly[..., 0], poly[..., 1]
    area = np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1)
    rev = poly[..., ::-1, :]
    return np.where((area < 0)[..., None, None], rev, poly)


def area_corners_board(light: "Light", pose) -> np.ndarray:
    """(4, 3) board-frame corners of an area light, in order around it."""
    m = light.to_world(pose)
    c = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1], [-1, 1, 0, 1]], float) @ m.T
    return (c[:, :3] - pose.translation_m) @ pose.rotation  # R^T (p - t), row vectors


def unit_irradiance_occluded(light: "Light", pose, points_board: np.ndarray, convex_polys: list,
                             height_m: float, faces_3d: list | None = None) -> np.ndarray:
    """Irradiance (per unit radiance) that an area light gives at board points (N, 2), z = 0, when the
    convex polygons ``convex_polys`` (each (m, 2), board frame, disjoint) held ``height_m`` in front of the
    board block it -- or, ``faces_3d``, a convex solid given by its faces ((m, 3) board-frame convex
    polygons, each wound counter-clockwise seen from outside; ``height_m``: its top's height).  Exact: the
    light's projected solid angle (Lambert's contour formula over its square) minus that of the blocked
    part.  From the point, that part is the cone over (the light's central projection onto the plane
    z = -height_m) n (the occluder's projection there): two convex polygons, whose common boundary is
    their edges clipped to each other; a solid's projection is tiled by its faces that face the point.
    Assumes the points see the light's emitting side and the light stands further from the board than
    ``height_m``."""
    x = np.column_stack([np.atleast_2d(points_board), np.zeros(len(np.atleast_2d(points_board)))])
    n = np.array([0.0, 0.0, -1.0])  # the board's normal towards the light (board frame: z into the board)
    lc = area_corners_board(light, pose)
    full = np.abs(lambert_sum(lc[None] - x[:, None], np.roll(lc, -1, 0)[None] - x[:, None], n))
    if np.any(-lc[:, 2] <= height_m):
        raise InputError(f"an area light at {list(light.position_m)} m does not stand further from the board than "
                         f"clutter {height_m:g} m high; raise the light or lower the item")

    def project(p3):  # points (..., 3) seen from each x, onto the plane z = -height_m: (N, ..., 2)
        k = height_m / -p3[..., 2]
        x2 = x[:, :2].reshape((len(x),) + (1,) * (p3.ndim - 1) + (2,))
        return x2 + k[None, ..., None] * (p3[None, ..., :2] - x2)

    q = _ccw(project(lc))  # (N, 4, 2): the light's image
    pieces = [(np.broadcast_to(_ccw(np.asarray(p, float)), (len(x),) + np.shape(p)), None) for p in convex_polys]
    for f in faces_3d or ():
        f = np.asarray(f, float)
        normal = np.cross(f[1] - f[0], f[2] - f[0])
        facing = (x - f.mean(axis=0)) @ normal > 0  # its projections tile the solid's: count each point once
        pieces.append((_ccw(project(f)), facing))
    blocked = np.zeros(len(x))
    for o, mask in pieces:
        a1, b1, ok1 = _clip_segments(o, np.roll(o, -1, axis=1), q)  # the occluder's edges inside the light's image
        a2, b2, ok2 = _clip_segments(q, np.roll(q, -1, axis=1), o)  # the light's edges inside the occluder's
        okk = np.concatenate([ok1, ok2], axis=1)
        z = np.full(okk.shape + (1,), -height_m)
        a3 = np.concatenate([np.concatenate([a1, a2], axis=1), z], axis=-1) - x[:, None]
        b3 = np.concatenate([np.concatenate([b1, b2], axis=1), z], axis=-1) - x[:, None]
        part = np.abs(lambert_sum(np.where(okk[..., None], a3, 0.0), np.where(okk[..., None], b3, 0.0), n))
        blocked += part if mask is None else np.where(mask, part, 0.0)
    return 0.5 * (full - blocked)
