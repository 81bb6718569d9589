"""The shape catalogue of the target scene: rectangles, circles, ellipses, rings and polygons on the board.

Pure data and geometry, no Mitsuba.  A ``Shape`` sits on the board at ``offset_m`` (board frame: x right,
y down from the board centre) turned by ``rotation_deg`` (from +x towards +y), printed flush: shape k
of a scene lies ``(k + 1) x TARGET_STANDOFF_M`` in front of the board, so a later shape covers an
earlier one.  A ring's hole shows the board (it covers what lies under it, like a disk with a white
centre).  Its outlines are straight sides (rectangle, polygon) or ellipses (circle, ellipse, ring: two);
``edgetruth.render.scene.outline.OutlineCurve`` carries them through the lens, and ``visible_intervals`` says
which parts of each outline are not covered by later shapes.

A ``TargetScene`` is what a target group shows: its shapes (shape 0 is the ranged target), the board's
material, its lights and an ambient term.  T1-T4 are presets of it, read from the shipped
``assets/targets.toml``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.scene.lights import Light
from edgetruth.render.scene.materials import BOARD_MATERIAL, Material
from edgetruth.render.schema import Key, parse_table

SHAPE_TYPES = ("rectangle", "circle", "ellipse", "ring", "polygon", "grid")
GRID_ELEMENTS = ("square", "circle")
MAX_GRID_ELEMENTS = 10000
MAX_SHAPES = 1000
MAX_VERTICES = 1000
#: samples per outline when finding where later shapes cover it (the ends are then bisected to 1e-13)
VISIBILITY_SAMPLES = 4096

_SIZE_KEYS = {"rectangle": ("width_m", "height_m"), "circle": ("diameter_m",), "ellipse": ("axes_m",),
              "ring": ("outer_diameter_m", "inner_diameter_m"), "polygon": ("vertices_m",),
              "grid": ("element_size_m", "pitch_m")}
#: a grid's own keys besides its sizes (refused on other types)
_GRID_KEYS = ("rows", "cols", "element")


def _rot(theta_rad: float) -> np.ndarray:
    c, s = math.cos(theta_rad), math.sin(theta_rad)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class Outline:
    """One closed outline of a shape in the board plane: a polygon (``vertices``, (n, 2) as tuples) or an
    ellipse (``conic`` = (cx, cy, a, b, theta_rad): semi-axes a along the turned x, b along y)."""

    name: str  # "outline", or a ring's "outer" / "inner"
    kind: str  # "polygon" | "ellipse"
    vertices: tuple | None = None
    conic: tuple | None = None

    def local_xy(self, t) -> np.ndarray:
        """(N, 2) board-frame points at parameters t in [0, 1): polygon side floor(n t) from vertex
        floor(n t) to the next; ellipse angle 2 pi t from its turned +x axis towards +y."""
        t = np.mod(np.asarray(t, float), 1.0)
        if self.kind == "polygon":
            v = np.asarray(self.vertices, float)
            n = len(v)
            k = np.minimum((n * t).astype(int), n - 1)
            s = n * t - k
            return v[k] + (np.roll(v, -1, axis=0)[k] - v[k]) * s[:, None]
        cx, cy, a, b, th = self.conic
        ang = 2 * np.pi * t
        return np.column_stack([a * np.cos(ang), b * np.sin(ang)]) @ _rot(th).T + [cx, cy]

    def corner_parameters(self) -> np.ndarray:
        return np.arange(len(self.vertices)) / len(self.vertices) if self.kind == "polygon" else np.zeros(0)


@dataclass(frozen=True)
class Shape:
    type: str
    offset_m: tuple = (0.0, 0.0)
    rotation_deg: float = 0.0
    width_m: float = 0.13
    height_m: float = 0.13
    diameter_m: float = 0.13
    axes_m: tuple = (0.13, 0.13)
    outer_diameter_m: float = 0.13
    inner_diameter_m: float = 0.065
    vertices_m: tuple = ()
    material: Material = field(default_factory=Material)
    # grid: rows x cols elements (squares of side / circles of diameter element_size_m), centres pitch_m apart
    rows: int = 1
    cols: int = 1
    pitch_m: tuple = (0.02, 0.02)
    element: str = "square"
    element_size_m: float = 0.01

    def grid_centres(self) -> np.ndarray:
        """(rows x cols, 2) board-frame element centres of a grid, row-major from the top-left element of
        the unturned grid (centred on ``offset_m``)."""
        r, c = np.meshgrid(np.arange(self.rows) - (self.rows - 1) / 2, np.arange(self.cols) - (self.cols - 1) / 2,
                           indexing="ij")
        return self._place(np.column_stack([c.ravel() * self.pitch_m[0], r.ravel() * self.pitch_m[1]]))

    def _place(self, xy: np.ndarray) -> np.ndarray:
        return np.asarray(xy, float) @ _rot(math.radians(self.rotation_deg)).T + np.asarray(self.offset_m)

    def outlines(self) -> list[Outline]:
        th = math.radians(self.rotation_deg)
        cx, cy = self.offset_m
        if self.type == "grid":  # one outline per element, named r<row>c<col>
            h = self.element_size_m / 2
            sq = np.array([[-h, -h], [h, -h], [h, h], [-h, h]]) @ _rot(th).T  # TL, TR, BR, BL, turned
            out = []
            for i, (ex, ey) in enumerate(self.grid_centres()):
                name = f"r{i // self.cols}c{i % self.cols}"
                if self.element == "square":
                    out.append(Outline(name, "polygon", vertices=tuple(map(tuple, sq + [ex, ey]))))
                else:
                    out.append(Outline(name, "ellipse", conic=(float(ex), float(ey), h, h, th)))
            return out
        if self.type == "rectangle":
            w, h = self.width_m / 2, self.height_m / 2
            v = self._place([[-w, -h], [w, -h], [w, h], [-w, h]])  # TL, TR, BR, BL of the unturned shape
            return [Outline("outline", "polygon", vertices=tuple(map(tuple, v)))]
        if self.type == "polygon":
            return [Outline("outline", "polygon", vertices=tuple(map(tuple, self._place(self.vertices_m))))]
        if self.type == "circle":
            r = self.diameter_m / 2
            return [Outline("outline", "ellipse", conic=(cx, cy, r, r, th))]
        if self.type == "ellipse":
            return [Outline("outline", "ellipse", conic=(cx, cy, self.axes_m[0] / 2, self.axes_m[1] / 2, th))]
        ro, ri = self.outer_diameter_m / 2, self.inner_diameter_m / 2
        return [Outline("outer", "ellipse", conic=(cx, cy, ro, ro, th)),
                Outline("inner", "ellipse", conic=(cx, cy, ri, ri, th))]

    def covers(self, xy: np.ndarray) -> np.ndarray:
        """Which board points (N, 2) this shape hides from view (a ring: its whole outer disk, the hole
        showing the board)."""
        xy = np.atleast_2d(np.asarray(xy, float))
        if self.type == "grid":
            out = np.zeros(len(xy), dtype=bool)
            for e in self.outlines():
                out |= Shape("polygon", vertices_m=e.vertices).covers(xy) if e.kind == "polygon" else \
                    Shape("circle", offset_m=e.conic[:2], diameter_m=2 * e.conic[2]).covers(xy)
            return out
        o = self.outlines()[0]
        if o.kind == "ellipse":
            cx, cy, a, b, th = o.conic
            q = (xy - [cx, cy]) @ _rot(th)
            return (q[:, 0] / a) ** 2 + (q[:, 1] / b) ** 2 < 1.0
        return point_in_polygon(np.asarray(o.vertices, float), xy)

    def sample_points(self, n: int = 64) -> np.ndarray:
        """(M, 2) points on the outer outline (corners included; a grid: every element's): for view checks."""
        if self.type == "grid":
            return np.concatenate([np.asarray(e.vertices, float) if e.kind == "polygon" else
                                   e.local_xy(np.arange(16) / 16) for e in self.outlines()])
        o = self.outlines()[0]
        if o.kind == "polygon":
            return np.asarray(o.vertices, float)
        return o.local_xy(np.arange(n) / n)

    def to_dict(self) -> dict:
        d = {"type": self.type, "offset_m": list(self.offset_m), "rotation_deg": self.rotation_deg}
        for k in _SIZE_KEYS[self.type]:
            v = getattr(self, k)
            d[k] = [list(p) for p in v] if k == "vertices_m" else (list(v) if isinstance(v, tuple) else v)
        if self.type == "grid":
            d.update(rows=self.rows, cols=self.cols, element=self.element)
        d["material"] = self.material.to_dict()
        return d


def point_in_polygon(poly: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Even-odd rule, vectorised over points."""
    x, y = xy[:, 0][:, None], xy[:, 1][:, None]
    x0, y0 = poly[:, 0][None], poly[:, 1][None]
    x1, y1 = np.roll(poly[:, 0], -1)[None], np.roll(poly[:, 1], -1)[None]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (np.sum(crosses & (x < xi), axis=1) % 2) == 1


def polygon_area2(v: np.ndarray) -> float:
    """Twice the signed (shoelace) area; > 0 for vertices clockwise on the board seen from the camera."""
    return float(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]))


def _segments_cross(p1, p2, q1, q2) -> bool:
    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    d1, d2, d3, d4 = orient(q1, q2, p1), orient(q1, q2, p2), orient(p1, p2, q1), orient(p1, p2, q2)
    return (d1 * d2 < 0) and (d3 * d4 < 0)


def check_simple_polygon(v: np.ndarray, where: str) -> None:
    n = len(v)
    if abs(polygon_area2(v)) < 1e-18:
        raise InputError(f"{where}: vertices_m enclose no area; list 3 or more points around the polygon")
    if np.any(np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1) == 0):
        raise InputError(f"{where}: vertices_m repeats a point; list each corner once")
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # neighbours
            if _segments_cross(v[i], v[(i + 1) % n], v[j], v[(j + 1) % n]):
                raise InputError(f"{where}: vertices_m: sides {i} and {j} cross; list the corners in order "
                                 "around a simple polygon")


def triangulate(v: np.ndarray) -> np.ndarray:
    """Ear clipping of a simple polygon: (n - 2, 3) vertex indices, each triangle wound like ``v`` after
    making its area positive (the caller reverses for Mitsuba)."""
    idx = list(range(len(v)))
    if polygon_area2(v) < 0:
        idx.reverse()
    tris = []
    guard = 0
    while len(idx) > 3 and guard < 10 * len(v) ** 2:
        guard += 1
        m = len(idx)
        for k in range(m):
            a, b, c = idx[k - 1], idx[k], idx[(k + 1) % m]
            pa, pb, pc = v[a], v[b], v[c]
            if (pb[0] - pa[0]) * (pc[1] - pa[1]) - (pb[1] - pa[1]) * (pc[0] - pa[0]) <= 0:
                continue  # reflex
            others = [i for i in idx if i not in (a, b, c)]
            if others and np.any(point_in_polygon(np.array([pa, pb, pc]), v[others])):
                continue
            tris.append((a, b, c))
            idx.pop(k)
            break
    tris.append(tuple(idx))
    return np.asarray(tris, dtype=np.int64)


def visible_intervals(outline: Outline, occluders: list[Shape], n: int = VISIBILITY_SAMPLES) -> list[list[float]]:
    """Parameter intervals [t0, t1] of ``outline`` that no shape in ``occluders`` covers (t1 may exceed 1:
    the interval wraps).  Ends are bisected to 1e-13 in t."""
    if not occluders:
        return [[0.0, 1.0]]

    def covered(t):
        xy = outline.local_xy(t)
        out = np.zeros(len(xy), dtype=bool)
        for s in occluders:
            out |= s.covers(xy)
        return out

    t = (np.arange(n) + 0.5) / n
    c = covered(t)
    if not c.any():
        return [[0.0, 1.0]]
    if c.all():
        return []

    def edge(ta, tb):  # covered(ta) != covered(tb): bisect to the change
        ca = covered(np.array([ta]))[0]
        for _ in range(60):
            tm = 0.5 * (ta + tb)
            if covered(np.array([tm]))[0] == ca:
                ta = tm
            else:
                tb = tm
            if tb - ta < 1e-13:
                break
        return 0.5 * (ta + tb)

    starts, ends = [], []
    for i in range(n):
        j = (i + 1) % n
        tj = t[j] + (1.0 if j == 0 else 0.0)
        if c[i] and not c[j]:
            starts.append(edge(t[i], tj) % 1.0)
        elif not c[i] and c[j]:
            ends.append(edge(t[i], tj) % 1.0)
    out = []
    for s0 in sorted(starts):
        e = min(ends, key=lambda e1: (e1 - s0) % 1.0)
        out.append([s0, s0 + (e - s0) % 1.0])
    return out


# --- spec keys ------------------------------------------------------------------------------------
SHAPE_KEYS = [
    Key("type", "str", "rectangle", "", "rectangle, circle, ellipse, ring (annulus; its hole shows the board), "
        "polygon or grid (rows x cols squares or circles, each element its own outline in the truth)",
        choices=SHAPE_TYPES),
    Key("offset_m", "vec2", (0.0, 0.0), "m", "the shape's centre (polygon: its vertices' origin) on the board, "
        "board frame (x right, y down from the board centre)", -100.0, 100.0),
    Key("rotation_deg", "float", 0.0, "deg", "turn about the board's normal, from +x towards +y", -360.0, 360.0),
    Key("width_m", "float", None, "m", "rectangle: side along its x (default: [spec] target_size_m)", 1e-5, 100.0),
    Key("height_m", "float", None, "m", "rectangle: side along its y (default: [spec] target_size_m)", 1e-5, 100.0),
    Key("diameter_m", "float", None, "m", "circle: diameter (default: [spec] target_size_m)", 1e-5, 100.0),
    Key("axes_m", "vec2", None, "m", "ellipse: [diameter along its x, along its y] (required)", 1e-5, 100.0),
    Key("outer_diameter_m", "float", None, "m", "ring: outer diameter (default: [spec] target_size_m)", 1e-5,
        100.0),
    Key("inner_diameter_m", "float", None, "m", "ring: hole diameter (required, < outer_diameter_m)", 1e-5, 100.0),
    Key("vertices_m", "points2", None, "m", "polygon: [[x, y], ...] corners in order around a simple polygon, "
        "in the shape's frame (turned by rotation_deg, moved by offset_m)", -100.0, 100.0),
    Key("rows", "int", 1, "", "grid: rows of elements", 1, 1000),
    Key("cols", "int", 1, "", "grid: columns of elements", 1, 1000),
    Key("element", "str", "square", "", "grid: its elements, squares or circles (as on Zhang's board)",
        choices=GRID_ELEMENTS),
    Key("element_size_m", "float", None, "m", "grid: an element's side (square) or diameter (circle) (required)",
        1e-5, 100.0),
    Key("pitch_m", "vec2", None, "m", "grid: [x, y] spacing of the element centres along the grid's (turned) "
        "axes, each > element_size_m (required); elements row-major from the top-left, outlines r<row>c<col>",
        1e-5, 100.0),
    Key("material", "table", {}, "", "the shape's material {type, albedo, alpha, eta, specular_reflectance, "
        "label} (default: black matte, albedo 0.04)"),
]


def shape_from_dict(d: dict, size_m: float, where: str, base_material: Material | None = None) -> Shape:
    """A ``Shape`` from a spec's shape table (sizes default to ``size_m``)."""
    v = parse_table(d, SHAPE_KEYS, where)
    typ = v["type"]
    wrong = sorted(k for k in d if k.endswith("_m") and k not in ("offset_m",) and k not in _SIZE_KEYS[typ])
    if typ != "grid":
        wrong += sorted(k for k in _GRID_KEYS if k in d)
    if wrong:
        raise InputError(f"{where}: {', '.join(wrong)} does not apply to type = {typ!r} (its size: "
                         f"{', '.join(_SIZE_KEYS[typ])}); remove it")
    kw = {"type": typ, "offset_m": v["offset_m"], "rotation_deg": v["rotation_deg"]}
    if typ == "rectangle":
        kw.update(width_m=v["width_m"] or size_m, height_m=v["height_m"] or size_m)
    elif typ == "circle":
        kw.update(diameter_m=v["diameter_m"] or size_m)
    elif typ == "grid":
        if v["element_size_m"] is None or v["pitch_m"] is None:
            raise InputError(f"{where}: a grid needs element_size_m and pitch_m = [x, y]; add them")
        if min(v["pitch_m"]) <= v["element_size_m"]:
            raise InputError(f"{where}: pitch_m = {list(v['pitch_m'])} must exceed element_size_m = "
                             f"{v['element_size_m']:g} m (elements must not touch); widen the pitch")
        if v["rows"] * v["cols"] > MAX_GRID_ELEMENTS:
            raise InputError(f"{where}: rows x cols = {v['rows'] * v['cols']} elements; at most {MAX_GRID_ELEMENTS}")
        kw.update(rows=v["rows"], cols=v["cols"], element=v["element"], element_size_m=v["element_size_m"],
                  pitch_m=v["pitch_m"])
    elif typ == "ellipse":
        if v["axes_m"] is None:
            raise InputError(f"{where}: an ellipse needs axes_m = [diameter along x, along y]; add it")
        kw.update(axes_m=v["axes_m"])
    elif typ == "ring":
        outer = v["outer_diameter_m"] or size_m
        if v["inner_diameter_m"] is None or v["inner_diameter_m"] >= outer:
            raise InputError(f"{where}: a ring needs inner_diameter_m < outer_diameter_m = {outer:g} m; add or "
                             "shrink it")
        kw.update(outer_diameter_m=outer, inner_diameter_m=v["inner_diameter_m"])
    else:
        if v["vertices_m"] is None:
            raise InputError(f"{where}: a polygon needs vertices_m = [[x, y], ...]; add it")
        if len(v["vertices_m"]) > MAX_VERTICES:
            raise InputError(f"{where}: vertices_m has {len(v['vertices_m'])} points; at most {MAX_VERTICES}")
        check_simple_polygon(np.asarray(v["vertices_m"]), where)
        kw.update(vertices_m=v["vertices_m"])
    kw["material"] = (base_material or Material()).merged(v["material"], f"{where} material")
    return Shape(**kw)


# --- clutter: raised planar shapes in front of the board ------------------------------------------
CLUTTER_TYPES = ("rectangle", "circle", "ellipse", "polygon", "grid")  # a ring's hole would need to be see-through
MIN_CLUTTER_HEIGHT_M = 1e-3


@dataclass(frozen=True)
class Clutter:
    """A catalogue shape held ``raised_m`` in front of the board, parallel to it (no visible support): it
    hides what lies behind it along the camera's rays and casts a shadow on the board."""

    shape: Shape
    raised_m: float

    def to_dict(self) -> dict:
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


def clutter_from_list(items: list, size_m: float, where: str) -> tuple:
    out = []
    for i, d in enumerate(items):
        w = f"{where}[{i}]"
        if not isinstance(d, dict):
            raise InputError(f"{w}: must be a table {{type, ..., raised_m}}")
        if "raised_m" not in d:
            raise InputError(f"{w}: raised_m missing: how far in front of the board the item stands; add it")
        h = d["raised_m"]
        if isinstance(h, bool) or not isinstance(h, (int, float)) or not MIN_CLUTTER_HEIGHT_M <= h <= 10.0:
            raise InputError(f"{w}: raised_m = {h!r}: give a number of metres in [{MIN_CLUTTER_HEIGHT_M:g}, 10]")
        shape = shape_from_dict({k: v for k, v in d.items() if k != "raised_m"}, size_m, w)
        if shape.type not in CLUTTER_TYPES:
            raise InputError(f"{w}: type = {shape.type!r} cannot stand as clutter (its hole would show the "
                             f"board's material); use one of {', '.join(CLUTTER_TYPES)}")
        if shape.material.texture:
            raise InputError(f"{w}: texture: clutter is not printed; remove it")
        out.append(Clutter(shape, float(h)))
    return tuple(out)


# --- the scene of a target group ------------------------------------------------------------------
@dataclass(frozen=True)
class TargetScene:
    """What a target group shows.  ``id``: the preset's name (T1-T4) or ``custom``."""

    id: str
    shapes: tuple
    board: Material = BOARD_MATERIAL
    lights: tuple = (Light(),)
    ambient: float = 0.0  # constant environment: irradiance on the open board, x the group's irradiance_w_m2
    clutter: tuple = ()  # ``Clutter`` items in front of the board

    @property
    def primary(self) -> Shape:
        return self.shapes[0]

    def __str__(self) -> str:  # the id where a target id is printed
        return self.id

    def sample_points(self) -> np.ndarray:
        """(M, 2) board points on every shape's outer outline."""
        return np.concatenate([s.sample_points() for s in self.shapes])

    def resolved(self) -> dict:
        out = {"id": self.id, "shapes": [s.to_dict() for s in self.shapes], "board": self.board.to_dict(),
               "lights": [lt.to_dict() for lt in self.lights], "ambient": self.ambient}
        if self.clutter:  # only when set: a scene without clutter keeps its identity
            out["clutter"] = [c.to_dict() for c in self.clutter]
        return out


def _load_presets() -> dict:
    """T1-T4 (and any other preset) from the shipped ``assets/targets.toml``: name -> (description, list of
    shape tables)."""
    from importlib import resources

    from edgetruth.fileio import read_toml

    path = resources.files("edgetruth.assets") / "targets.toml"
    data = read_toml(path)
    return {name: (t.get("description", ""), t["shape"]) for name, t in data.items()}


PRESETS = _load_presets()


def preset_scene(name: str, size_m: float) -> TargetScene:
    desc, shapes = PRESETS[name]
    return TargetScene(id=name, shapes=tuple(shape_from_dict(s, size_m, f"assets/targets.toml [{name}] shape")
                                             for s in shapes))


def legacy_targets() -> dict:
    """The ``TARGETS`` table (id -> shape, material, reflectance, ...) the fixed T1-T4 scene reads, derived
    from the presets (a square or a circle of one material each)."""
    out = {}
    for name in PRESETS:
        s = preset_scene(name, 0.13).primary
        m = s.material
        d = {"shape": "square" if s.type == "rectangle" else "circle", "material": m.label,
             "reflectance": m.albedo}
        if m.type == "roughplastic":
            d.update(alpha=m.alpha, eta=m.eta)
        out[name] = d
    return out


SCENE_GROUP_KEYS = ("shapes", "target_material", "board_material", "lights", "ambient", "clutter")


def scene_from_group(g: dict, raw: dict, size_m: float, light_position_m, where: str,
                     base_dir=None) -> TargetScene | None:
    """The group's ``TargetScene`` when it sets any scene key (else None: the fixed preset scene).
    ``base_dir``: where relative texture paths start (the spec's folder)."""
    if not any(k in raw for k in SCENE_GROUP_KEYS):
        return None
    from edgetruth.render.scene.lights import lights_from_list

    if raw.get("shapes") is not None:
        if "target" in raw:
            raise InputError(f"{where}: target = {raw['target']!r} and shapes: shapes replace the preset's shapes; "
                             "remove one of them")
        items = g["shapes"]
        if len(items) > MAX_SHAPES:
            raise InputError(f"{where}: shapes: {len(items)} shapes; at most {MAX_SHAPES}")
        shapes = [shape_from_dict(s, size_m, f"{where} shapes[{i}]") for i, s in enumerate(items)]
        sid = "custom"
    else:
        base = preset_scene(g["target"], size_m)
        shapes, sid = list(base.shapes), base.id
    if "target_material" in raw:
        shapes[0] = replace(shapes[0], material=shapes[0].material.merged(g["target_material"],
                                                                          f"{where} target_material"))
    board = BOARD_MATERIAL.merged(g["board_material"], f"{where} board_material") if "board_material" in raw \
        else BOARD_MATERIAL
    from edgetruth.render.scene.materials import with_texture_file

    board = with_texture_file(board, base_dir, f"{where} board_material")
    for i, sh in enumerate(shapes):
        if sh.material.texture:
            w = f"{where} {'shapes[%d]' % i if raw.get('shapes') is not None else 'target_material'} material"
            if sh.type != "rectangle":
                raise InputError(f"{w}: texture prints on a rectangle shape or the board only (this shape is a "
                                 f"{sh.type}); remove it or use a rectangle")
            shapes[i] = replace(sh, material=with_texture_file(sh.material, base_dir, w))
    if "lights" in raw:
        if "light_position_m" in raw:
            raise InputError(f"{where}: lights and light_position_m: light_position_m moves the default light; "
                             "give the position in each light instead")
        lights = lights_from_list(g["lights"], f"{where} lights")
    else:
        lights = (Light(position_m=tuple(light_position_m)),)
    clutter = clutter_from_list(g["clutter"], size_m, f"{where} clutter") if raw.get("clutter") is not None else ()
    return TargetScene(id=sid, shapes=tuple(shapes), board=board, lights=lights, ambient=float(g.get("ambient", 0.0)),
                       clutter=clutter)

