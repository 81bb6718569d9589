"""Clutter in front of the board: raised planar shapes (``Clutter``) and boxes standing on it (``Box``: a
cuboid whose image bounds the board along its silhouette, ``Box.silhouette``); both hide what lies behind them
and cast shadows (``shadow_outline``, ``Box.shadow_polygon``), drawn as the covers and occluder polygons that
``edgetruth.render.scene.shapes.visible_intervals`` asks.  Pure data and geometry, no Mitsuba."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.scene.materials import Material
from edgetruth.render.scene.polygons import convex_hull, point_in_polygon, rot, triangulate
from edgetruth.render.scene.shapes import Outline, Shape, shape_from_dict
from edgetruth.render.schema import REQUIRED, Key, parse_table


# --- clutter: raised planar shapes in front of the board ------------------------------------------
#: a ring's hole, a checkerboard's light squares would need to be see-through
CLUTTER_TYPES = ("rectangle", "circle", "ellipse", "polygon", "grid")
MIN_CLUTTER_HEIGHT_M = 1e-3


@dataclass(frozen=True)
class Clutter:
    """A catalogue shape held ``raised_m`` in front of the board, parallel to it (no visible support): it
    hides what lies behind it along the camera's rays and casts a shadow on the board."""

    shape: Shape  # or a ``Box`` (then ``raised_m`` is unused: it stands on the board)
    raised_m: float

    @property
    def is_box(self) -> bool:
        return isinstance(self.shape, Box)

    @property
    def top_m(self) -> float:
        """How far its nearest point stands in front of the board."""
        return self.shape.base_m + self.shape.size_m[2] if self.is_box else self.raised_m

    def to_dict(self) -> dict:
        if self.is_box:
            return self.shape.to_dict()
        return {**self.shape.to_dict(), "raised_m": self.raised_m}


@dataclass(frozen=True)
class RaisedCover:
    """What a ``Clutter`` item hides, seen from ``eye_board_m`` (the camera centre in the board frame), of
    points ``source_height_m`` in front of the board: the ray from the eye to such a point crosses the
    item's plane inside the item."""

    clutter: Clutter
    eye_board_m: tuple
    source_height_m: float

    def covers(self, xy: np.ndarray) -> np.ndarray:
        xy = np.atleast_2d(np.asarray(xy, float))
        if self.clutter.raised_m <= self.source_height_m:
            return np.zeros(len(xy), dtype=bool)
        e = np.asarray(self.eye_board_m, float)
        t = (-self.clutter.raised_m - e[2]) / (-self.source_height_m - e[2])  # board frame: z = -height
        return self.clutter.shape.covers(e[:2] + t * (xy - e[:2]))

    def covers_xyz(self, p: np.ndarray) -> np.ndarray:
        """As ``covers`` for board-frame points (N, 3) at any heights (a box's silhouette)."""
        p = np.atleast_2d(np.asarray(p, float))
        e = np.asarray(self.eye_board_m, float)
        behind = -p[:, 2] < self.clutter.raised_m
        t = (-self.clutter.raised_m - e[2]) / (p[:, 2] - e[2])
        return behind & self.clutter.shape.covers(e[:2] + t[:, None] * (p[:, :2] - e[:2]))


def shadow_outline(o: Outline, height_m: float, light_board_m) -> Outline | None:
    """The shadow on the board (z = 0) of outline ``o`` held ``height_m`` in front of it, cast by a point
    light at ``light_board_m`` (board frame, z < 0 in front): parallel planes, so the central projection is
    a scaling by D / (D - h) about the light's foot (D: the light's height).  None if the light is not
    further from the board than the outline."""
    fx, fy, fz = (float(c) for c in light_board_m)
    d = -fz
    if d <= height_m:
        return None
    k = d / (d - height_m)
    if o.kind == "polygon":
        v = np.asarray(o.vertices, float)
        return Outline(o.name, "polygon", vertices=tuple(map(tuple, [fx, fy] + k * (v - [fx, fy]))))
    cx, cy, a, b, th = o.conic
    return Outline(o.name, "ellipse", conic=(fx + k * (cx - fx), fy + k * (cy - fy), k * a, k * b, th))


# --- boxes: solids standing on the board ----------------------------------------------------------
@dataclass(frozen=True)
class Box:
    """A cuboid standing on the board: sides ``size_m`` = (x, y, z) along its turned x, its turned y and the
    board's normal (its height), its base centred at ``offset_m``, turned by ``rotation_deg`` about the
    board's normal, its base ``base_m`` in front of the board (on top of the printed shapes).  Its
    faces are planar, so every edge of its image is a straight 3-D segment through the lens: the outline
    where it bounds what lies behind it is the silhouette seen from the camera (``silhouette``), a polygon
    of its corners; from a point light its shadow on the board is the convex hull of its corners' central
    projections (``shadow_polygon``)."""

    size_m: tuple
    offset_m: tuple = (0.0, 0.0)
    rotation_deg: float = 0.0
    material: Material = field(default_factory=Material)
    base_m: float = 2 * 10e-6
    type: str = "box"

    def corners(self) -> np.ndarray:
        """(8, 3) board-frame corners: the base's TL, TR, BR, BL (unturned frame, z = -base_m), then the
        top's in the same order (z = -base_m - size z)."""
        hx, hy = self.size_m[0] / 2, self.size_m[1] / 2
        xy = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]) @ rot(math.radians(self.rotation_deg)).T \
            + np.asarray(self.offset_m, float)
        z0, z1 = -self.base_m, -self.base_m - self.size_m[2]
        return np.concatenate([np.column_stack([xy, np.full(4, z0)]), np.column_stack([xy, np.full(4, z1)])])

    def footprint(self) -> np.ndarray:
        return self.corners()[:4, :2]

    def faces(self) -> np.ndarray:
        """(10, 3) triangles over ``corners`` (the four sides and the top; the base faces the board and is
        never seen), each wound so that its normal (p1 - p0) x (p2 - p0) points out of the box."""
        quads = [(4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]  # the top, then the sides
        c = self.corners()
        mid = c.mean(axis=0)
        tris = []
        for q in quads:
            for tri in ((q[0], q[1], q[2]), (q[0], q[2], q[3])):
                p = c[list(tri)]
                if np.dot(np.cross(p[1] - p[0], p[2] - p[0]), p.mean(axis=0) - mid) < 0:
                    tri = tri[::-1]
                tris.append(tri)
        return np.asarray(tris, dtype=np.int64)

    def quads(self) -> np.ndarray:
        """(6, 4, 3) its faces (the base included), each wound counter-clockwise seen from outside (its
        normal (p1 - p0) x (p2 - p0) points out)."""
        c = self.corners()
        mid = c.mean(axis=0)
        out = []
        for q in [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]:
            p = c[list(q)]
            if np.dot(np.cross(p[1] - p[0], p[2] - p[0]), p.mean(axis=0) - mid) < 0:
                p = p[::-1]
            out.append(p)
        return np.asarray(out)

    def _local(self, p: np.ndarray) -> np.ndarray:
        """Board-frame points (N, 3) in the box's own frame: x, y along its turned sides, z along the board's z,
        all from the box's centre."""
        q = np.asarray(p, float)
        xy = (q[:, :2] - np.asarray(self.offset_m, float)) @ rot(math.radians(self.rotation_deg))
        return np.column_stack([xy, q[:, 2] + self.base_m + self.size_m[2] / 2])

    def segment_hits(self, eye_board_m, points_board_m: np.ndarray) -> np.ndarray:
        """Whether the segment from ``eye_board_m`` to each point passes through the box's interior (slabs;
        a segment that only touches its surface -- a silhouette point, a point on it -- does not)."""
        p = self._local(np.atleast_2d(points_board_m))
        e = self._local(np.asarray(eye_board_m, float)[None])[0]
        d = p - e
        half = np.array([self.size_m[0] / 2, self.size_m[1] / 2, self.size_m[2] / 2])
        lo, hi = np.zeros(len(p)), np.ones(len(p))
        with np.errstate(divide="ignore", invalid="ignore"):
            for k in range(3):
                t0, t1 = (-half[k] - e[k]) / d[:, k], (half[k] - e[k]) / d[:, k]
                par = d[:, k] == 0
                ta, tb = np.minimum(t0, t1), np.maximum(t0, t1)
                inside = np.abs(e[k]) < half[k]
                # a segment parallel to the slab: all of it inside (the eye's coordinate within) or none
                ta = np.where(par, np.where(inside, -np.inf, np.inf), ta)
                tb = np.where(par, np.where(inside, np.inf, -np.inf), tb)
                lo, hi = np.maximum(lo, ta), np.minimum(hi, tb)
        # an interior crossing: a run of positive length (relative 1e-9 of the segment: the surface's own
        # points and grazing silhouette rays are not hidden)
        return hi - lo > 1e-9

    def silhouette(self, eye_board_m) -> np.ndarray:
        """(n, 3) board-frame corners of the box's silhouette seen from ``eye_board_m``, in order around it: the
        convex hull of the corners' central projections (a convex solid's outline is the hull of its
        vertices' images; each hull side is the image of a straight segment between two corners)."""
        c = self.corners()
        e = np.asarray(eye_board_m, float)
        axis = c.mean(axis=0) - e
        axis /= np.linalg.norm(axis)
        depth = (c - e) @ axis
        if np.any(depth <= 0):
            raise InputError(f"a box at {list(self.offset_m)} m reaches behind the camera; move or shrink it")
        u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        w = np.cross(axis, u)
        q = np.column_stack([(c - e) @ u, (c - e) @ w]) / depth[:, None]
        return c[convex_hull(q)]

    def shadow_polygon(self, light_board_m) -> np.ndarray | None:
        """(m, 2) board-frame shadow of the box on the board (z = 0) from a point light at ``light_board_m``
        (z < 0 in front): the convex hull of its corners' central projections; None when the light is not
        above the box's top."""
        L = np.asarray(light_board_m, float)
        c = self.corners()
        if -L[2] <= -c[:, 2].min() + 1e-12:
            return None
        s = L[2] / (L[2] - c[:, 2])  # along light -> corner to z = 0
        xy = L[:2] + s[:, None] * (c[:, :2] - L[:2])
        return xy[convex_hull(xy)]

    def to_dict(self) -> dict:
        return {"type": "box", "offset_m": list(self.offset_m), "rotation_deg": self.rotation_deg,
                "size_m": list(self.size_m), "base_m": self.base_m, "material": self.material.to_dict()}


#: vertices of the polygon standing in for a conic where an area light's shadow needs polygons (its chords
#: stay within r (1 - cos(pi / n)) = 2.4e-6 r of the conic)
CONIC_POLYGON_VERTICES = 1440


def occluder_polygons(shape: Shape) -> tuple[list, bool]:
    """Convex board-frame polygons (each (m, 2)) whose union is ``shape`` (a polygon: its ear-clipped
    triangles unless it is convex; a grid: its elements; a conic: a ``CONIC_POLYGON_VERTICES``-gon), and
    whether they are exact (no conic)."""
    exact = True
    out = []
    for o in shape.outlines():
        if o.kind == "ellipse":
            out.append(o.local_xy(np.arange(CONIC_POLYGON_VERTICES) / CONIC_POLYGON_VERTICES))
            exact = False
            continue
        v = np.asarray(o.vertices, float)
        if len(convex_hull(v)) == len(v):
            out.append(v)
        else:
            out += [v[t] for t in triangulate(v)]
    return out, exact


@dataclass(frozen=True)
class SpaceOutline:
    """A closed polygon of 3-D board-frame points (a box's silhouette): parameter t in [0, 1), side floor(n t)
    from vertex floor(n t) to the next, straight in space (so straight in the undistorted image)."""

    name: str
    vertices: tuple  # (n, 3)
    kind: str = "polygon"

    def local_xyz(self, t) -> np.ndarray:
        t = np.mod(np.asarray(t, float), 1.0)
        v = np.asarray(self.vertices, float)
        n = len(v)
        k = np.minimum((n * t).astype(int), n - 1)
        s = n * t - k
        return v[k] + (np.roll(v, -1, axis=0)[k] - v[k]) * s[:, None]

    def local_xy(self, t) -> np.ndarray:
        return self.local_xyz(t)[:, :2]

    def corner_parameters(self) -> np.ndarray:
        return np.arange(len(self.vertices)) / len(self.vertices)


@dataclass(frozen=True)
class BoxCover:
    """What a box hides, seen from ``eye_board_m``, of points ``source_height_m`` in front of the board (or,
    ``covers_xyz``, of any board-frame points): the segment from the eye to the point crosses the box."""

    box: Box
    eye_board_m: tuple
    source_height_m: float = 0.0

    def covers(self, xy: np.ndarray) -> np.ndarray:
        xy = np.atleast_2d(np.asarray(xy, float))
        return self.covers_xyz(np.column_stack([xy, np.full(len(xy), -self.source_height_m)]))

    def covers_xyz(self, p: np.ndarray) -> np.ndarray:
        return self.box.segment_hits(self.eye_board_m, p)


@dataclass(frozen=True)
class FootprintCover:
    """Board points within ``margin_m`` of a box's footprint (inside or on it): a box's own shadow outline
    there runs under its base edge, where the image shows the box, not a shadow edge."""

    box: Box
    margin_m: float

    def covers(self, xy: np.ndarray) -> np.ndarray:
        xy = np.atleast_2d(np.asarray(xy, float))
        v = self.box.footprint()
        a, b = v, np.roll(v, -1, axis=0)
        d = b - a
        t = np.clip(((xy[:, None] - a) * d).sum(2) / (d * d).sum(1), 0, 1)
        dist = np.min(np.linalg.norm(xy[:, None] - (a + t[..., None] * d), axis=2), axis=1)
        return point_in_polygon(v, xy) | (dist <= self.margin_m)


BOX_KEYS = [
    Key("type", "str", "box", "", "box: a cuboid standing on the board (on its printed shapes)", choices=("box",)),
    Key("offset_m", "vec2", (0.0, 0.0), "m", "the centre of its base on the board, board frame (x right, y down)",
        -100.0, 100.0),
    Key("rotation_deg", "float", 0.0, "deg", "turn about the board's normal, from +x towards +y", -360.0, 360.0),
    Key("size_m", "vec3", REQUIRED, "m", "[x, y, z]: its sides along its (turned) x and y, and its height off the "
        "board (required)", 1e-4, 10.0),
    Key("material", "table", {}, "", "its material {type, albedo, alpha, eta, specular_reflectance, label} "
        "(default: black matte, albedo 0.04; no texture)"),
]


def box_from_dict(d: dict, where: str, base_m: float) -> Box:
    if "raised_m" in d:
        raise InputError(f"{where}: raised_m does not apply to a box (it stands on the board; its height is "
                         "size_m's third value); remove it")
    v = parse_table(d, BOX_KEYS, where)
    mat = Material().merged(v["material"], f"{where} material")
    if mat.texture:
        raise InputError(f"{where}: texture: clutter is not printed; remove it")
    return Box(size_m=tuple(float(c) for c in v["size_m"]), offset_m=tuple(v["offset_m"]),
               rotation_deg=float(v["rotation_deg"]), material=mat, base_m=float(base_m))


def clutter_from_list(items: list, size_m: float, where: str, box_base_m: float = 2 * 10e-6) -> tuple:
    """Clutter items from a spec's ``clutter = [...]``: raised planar shapes and boxes (standing
    ``box_base_m`` in front of the board: on the scene's prints)."""
    out = []
    for i, d in enumerate(items):
        w = f"{where}[{i}]"
        if not isinstance(d, dict):
            raise InputError(f"{w}: must be a table {{type, ..., raised_m}}")
        if d.get("type") == "box":
            out.append(Clutter(box_from_dict(d, w, box_base_m), 0.0))
            continue
        if "raised_m" not in d:
            raise InputError(f"{w}: raised_m missing: how far in front of the board the item stands; add it")
        h = d["raised_m"]
        if isinstance(h, bool) or not isinstance(h, (int, float)) or not MIN_CLUTTER_HEIGHT_M <= h <= 10.0:
            raise InputError(f"{w}: raised_m = {h!r}: give a number of metres in [{MIN_CLUTTER_HEIGHT_M:g}, 10]")
        shape = shape_from_dict({k: v for k, v in d.items() if k != "raised_m"}, size_m, w)
        if shape.type not in CLUTTER_TYPES:
            raise InputError(f"{w}: type = {shape.type!r} cannot stand as clutter (its hole or light "
                             f"squares would show the board's material); use one of {', '.join(CLUTTER_TYPES)} or box")
        if shape.material.texture:
            raise InputError(f"{w}: texture: clutter is not printed; remove it")
        out.append(Clutter(shape, float(h)))
    return tuple(out)


