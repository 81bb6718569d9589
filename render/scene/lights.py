"""Lights of the target scene: square area lights, point and spot lights, and a constant ambient term.

Pure data and geometry (no Mitsuba).  A light's power is stated as the irradiance it gives at its aim
point on the board (``share`` x the group's ``irradiance_w_m2``), so a design's power levels and the
radiance units (which scale a render by irradiance) keep their meaning with any set of lights.  Each
image's ground truth records every light with its emission and the irradiance it gives at the board
centre and at every shape's centre (``irradiance_at``; nothing on the flat board can shadow it).
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
