"""The shape catalogue of the target scene: rectangles, circles, ellipses, rings and polygons on the board.

Pure data and geometry, no Mitsuba.  A ``Shape`` sits on the board at ``offset_m`` (board frame: x right,
y down from the board centre) turned by ``rotation_deg`` (from +x towards +y), printed flush: shape k
of a scene lies ``(k + 1) x TARGET_STANDOFF_M`` in front of the board, so a later shape covers an
earlier one.  A ring's hole shows the board (it covers what lies under it, like a disk with a white
centre).  Its outlines are straight sides (rectangle, polygon) or ellipses (circle, ellipse, ring: two);
``edgetruth.render.scene.outline.OutlineCurve`` carries them through the lens, and ``visible_intervals`` says
which parts of each outline are not covered by later shapes.

A shape's printed texture fills its bounding box in its own frame (``Shape.texture_frame``), turned and
moved with it.  Clutter stands in front of the board: raised planar shapes (``Clutter``) and boxes standing
on it (``Box``: a cuboid whose image bounds the board along its silhouette, ``Box.silhouette``); both hide
what lies behind them and cast shadows (``shadow_outline``, ``Box.shadow_polygon``).

A ``TargetScene`` is what a target group shows: its shapes (shape 0 is the ranged target), the board's
material, its lights, an ambient term and its clutter.  T1-T4 are presets of it, read from the shipped
``assets/targets.toml``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.scene.lights import Light
from edgetruth.render.scene.materials import BOARD_MATERIAL, Material
from edgetruth.render.schema import REQUIRED, Key, parse_table

#: Targets are mounted flush on the board: 10 um stand-off, only to avoid coplanar surfaces
#: (a real stand-off casts ambient-occlusion shading that moves the edge; BRIEF §1).
TARGET_STANDOFF_M = 10e-6
#: the board's default half width and height: fills the frame at 3 m with room for lateral offsets (a target
#: group's ``board_size_m`` sets its own: ``TargetScene.board_half_size_m``)
BOARD_HALF_SIZE_M = (1.8, 1.5)
SHAPE_TYPES = ("rectangle", "circle", "ellipse", "ring", "polygon", "grid", "checkerboard")
GRID_ELEMENTS = ("square", "circle")
MAX_GRID_ELEMENTS = 10000
MAX_SHAPES = 1000
MAX_VERTICES = 1000
#: samples per outline when finding where later shapes cover it (the ends are then bisected to 1e-13)
VISIBILITY_SAMPLES = 4096

_SIZE_KEYS = {"rectangle": ("width_m", "height_m"), "circle": ("diameter_m",), "ellipse": ("axes_m",),
              "ring": ("outer_diameter_m", "inner_diameter_m"), "polygon": ("vertices_m",),
              "grid": ("element_size_m", "pitch_m"), "checkerboard": ("square_m",)}
#: a grid's (and a checkerboard's: rows, cols) own keys besides its sizes (refused on other types)
_GRID_KEYS = ("rows", "cols", "element")
_CHECKER_KEYS = ("rows", "cols")


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
    # checkerboard: rows x cols squares of side square_m, centred on offset_m; the dark squares are (row + col)
    # even (row 0, col 0 at the top-left of the unturned board), the light squares are not printed: the board
    square_m: float = 0.03

    def checker_cells(self) -> np.ndarray:
        """(n, 2) (row, col) of a checkerboard's dark squares, row-major from the top-left square."""
        r, c = np.divmod(np.arange(self.rows * self.cols), self.cols)
        even = (r + c) % 2 == 0
        return np.column_stack([r[even], c[even]])

    def checker_quads_local(self) -> np.ndarray:
        """(n, 4, 2) corners of a checkerboard's dark squares in its own frame (before its turn and offset),
        ``checker_cells`` order, each top-left, top-right, bottom-right, bottom-left.  The arithmetic is
        ``targets.Checkerboard``'s (x0 = (col - cols/2) s, x0 + s): the same floats to the bit, so a
        ``kind = "checkerboard"`` group's mesh is this preset's geometry exactly."""
        s = self.square_m
        quads = []
        for j, i in self.checker_cells():
            x0 = (int(i) - self.cols / 2) * s
            y0 = (int(j) - self.rows / 2) * s
            quads.append([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]])
        return np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)

    def inner_corners_local(self) -> np.ndarray:
        """((rows - 1) x (cols - 1), 2) a checkerboard's inner corners (where four squares meet) in its own
        frame, row-major, x fastest (``cv2.findChessboardCorners``'s order for an untilted board)."""
        xs = (np.arange(1, self.cols) - self.cols / 2) * self.square_m
        ys = (np.arange(1, self.rows) - self.rows / 2) * self.square_m
        gx, gy = np.meshgrid(xs, ys)
        return np.column_stack([gx.ravel(), gy.ravel()])

    def inner_corners(self) -> np.ndarray:
        """A checkerboard's inner corners on the board (board frame), ``inner_corners_local`` order."""
        return self._place(self.inner_corners_local())

    def grid_centres(self) -> np.ndarray:
        """(rows x cols, 2) board-frame element centres of a grid, row-major from the top-left element of
        the unturned grid (centred on ``offset_m``)."""
        return self._place(self.grid_centres_local())

    def _place(self, xy: np.ndarray) -> np.ndarray:
        return np.asarray(xy, float) @ _rot(math.radians(self.rotation_deg)).T + np.asarray(self.offset_m)

    def texture_frame(self) -> tuple:
        """(x0, y0, x1, y1): the box a printed texture fills, in the shape's own frame (before its turn and
        offset; y down): the shape's bounding box -- a rectangle itself, a circle's or a ring's outer square,
        an ellipse's axes, a polygon's vertices' extent, a grid's outer element edges."""
        if self.type == "rectangle":
            w, h = self.width_m / 2, self.height_m / 2
        elif self.type == "circle":
            w = h = self.diameter_m / 2
        elif self.type == "ellipse":
            w, h = self.axes_m[0] / 2, self.axes_m[1] / 2
        elif self.type == "ring":
            w = h = self.outer_diameter_m / 2
        elif self.type == "grid":
            w = ((self.cols - 1) * self.pitch_m[0] + self.element_size_m) / 2
            h = ((self.rows - 1) * self.pitch_m[1] + self.element_size_m) / 2
        elif self.type == "checkerboard":
            w, h = self.cols * self.square_m / 2, self.rows * self.square_m / 2
        else:
            v = np.asarray(self.vertices_m, float)
            return (float(v[:, 0].min()), float(v[:, 1].min()), float(v[:, 0].max()), float(v[:, 1].max()))
        return (-w, -h, w, h)

    def texture_corners(self) -> np.ndarray:
        """(4, 2) board-frame corners of the printed image: its top-left, top-right, bottom-right, bottom-left
        (``texture_frame`` turned and moved; a rectangle's are its own corners)."""
        x0, y0, x1, y1 = self.texture_frame()
        return self._place([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])

    def texture_uv(self, ex: float, ey: float, a: float, b: float) -> tuple:
        """(u0, ux, uy, v0, vx, vy): texture coordinates u = u0 + ux x + uy y, v = v0 + vx x + vy y of the
        local point (x, y) in [-1, 1]^2 of a Mitsuba rectangle or unit disk that covers the shape-frame
        points (ex + a x, ey - b y) (``_shape_local``'s map); v = 1 is the image's top row (it is stored
        flipped)."""
        x0, y0, x1, y1 = self.texture_frame()
        w, h = x1 - x0, y1 - y0
        return ((ex - x0) / w, a / w, 0.0, (y1 - ey) / h, 0.0, b / h)

    def grid_centres_local(self) -> np.ndarray:
        """(rows x cols, 2) element centres of a grid in its own frame (before the turn and offset)."""
        r, c = np.meshgrid(np.arange(self.rows) - (self.rows - 1) / 2, np.arange(self.cols) - (self.cols - 1) / 2,
                           indexing="ij")
        return np.column_stack([c.ravel() * self.pitch_m[0], r.ravel() * self.pitch_m[1]])

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
        if self.type == "checkerboard":  # one closed outline per dark square, named r<row>c<col>
            q = self.checker_quads_local()
            placed = self._place(q.reshape(-1, 2)).reshape(q.shape)
            return [Outline(f"r{j}c{i}", "polygon", vertices=tuple(map(tuple, v)))
                    for (j, i), v in zip(self.checker_cells(), placed)]
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
        if self.type == "checkerboard":  # the dark squares only: the light ones show what lies under them
            q = (xy - np.asarray(self.offset_m, float)) @ _rot(math.radians(self.rotation_deg))
            c = np.floor(q[:, 0] / self.square_m + self.cols / 2)
            r = np.floor(q[:, 1] / self.square_m + self.rows / 2)
            return (c >= 0) & (c < self.cols) & (r >= 0) & (r < self.rows) & ((r + c) % 2 == 0)
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
        if self.type == "checkerboard":
            return np.concatenate([np.asarray(e.vertices, float) for e in self.outlines()])
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
        if self.type == "checkerboard":
            d.update(rows=self.rows, cols=self.cols, pattern_size=[self.cols - 1, self.rows - 1],
                     dark_squares="(row + col) even, row 0 col 0 at the top-left of the unturned board; the light "
                                  "squares are not printed (they show the board)")
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
    the interval wraps).  Ends are bisected to 1e-13 in t.  A ``SpaceOutline`` (3-D points) asks each
    occluder's ``covers_xyz``."""
    if not occluders:
        return [[0.0, 1.0]]

    space = hasattr(outline, "local_xyz")  # a box's silhouette: its points at their own heights

    def covered(t):
        xy = outline.local_xyz(t) if space else outline.local_xy(t)
        out = np.zeros(len(xy), dtype=bool)
        for s in occluders:
            out |= s.covers_xyz(xy) if space else s.covers(xy)
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
        "polygon, grid (rows x cols squares or circles, each element its own outline in the truth) or "
        "checkerboard (rows x cols squares of square_m, the dark ones (row + col even) printed in its material, "
        "the light ones showing the board; each dark square its own outline r<row>c<col>, the inner corners in "
        "the truth)",
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
    Key("rows", "int", 1, "", "grid: rows of elements; checkerboard: rows of squares (>= 2)", 1, 1000),
    Key("cols", "int", 1, "", "grid: columns of elements; checkerboard: columns of squares (>= 2)", 1, 1000),
    Key("element", "str", "square", "", "grid: its elements, squares or circles (as on Zhang's board)",
        choices=GRID_ELEMENTS),
    Key("element_size_m", "float", None, "m", "grid: an element's side (square) or diameter (circle) (required)",
        1e-5, 100.0),
    Key("pitch_m", "vec2", None, "m", "grid: [x, y] spacing of the element centres along the grid's (turned) "
        "axes, each > element_size_m (required); elements row-major from the top-left, outlines r<row>c<col>",
        1e-5, 100.0),
    Key("square_m", "float", None, "m", "checkerboard: side of one square (required); the board spans cols x "
        "rows squares centred on offset_m", 1e-5, 100.0),
    Key("material", "table", {}, "", "the shape's material {type, albedo, alpha, eta, specular_reflectance, "
        "label} (default: black matte, albedo 0.04; checkerboard: its dark squares')"),
]


def shape_from_dict(d: dict, size_m: float, where: str, base_material: Material | None = None) -> Shape:
    """A ``Shape`` from a spec's shape table (sizes default to ``size_m``)."""
    v = parse_table(d, SHAPE_KEYS, where)
    typ = v["type"]
    wrong = sorted(k for k in d if k.endswith("_m") and k not in ("offset_m",) and k not in _SIZE_KEYS[typ])
    if typ != "grid":
        wrong += sorted(k for k in _GRID_KEYS if k in d and not (typ == "checkerboard" and k in _CHECKER_KEYS))
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
    elif typ == "checkerboard":
        if v["square_m"] is None:
            raise InputError(f"{where}: a checkerboard needs square_m (the side of one square, m); add it")
        if v["rows"] < 2 or v["cols"] < 2:
            raise InputError(f"{where}: a checkerboard of rows = {v['rows']}, cols = {v['cols']} squares has no "
                             "inner corner; give rows >= 2 and cols >= 2")
        if v["rows"] * v["cols"] > MAX_GRID_ELEMENTS:
            raise InputError(f"{where}: rows x cols = {v['rows'] * v['cols']} squares; at most {MAX_GRID_ELEMENTS}")
        kw.update(rows=v["rows"], cols=v["cols"], square_m=v["square_m"])
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
        xy = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]) @ _rot(math.radians(self.rotation_deg)).T \
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
        xy = (q[:, :2] - np.asarray(self.offset_m, float)) @ _rot(math.radians(self.rotation_deg))
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


def convex_hull(q: np.ndarray) -> np.ndarray:
    """Indices of the convex hull of 2-D points (N, 2), counter-clockwise in (x, y), collinear points left out
    (Andrew's monotone chain)."""
    q = np.asarray(q, float)
    order = sorted(range(len(q)), key=lambda i: (q[i, 0], q[i, 1]))

    def cross(o, a, b):
        return (q[a, 0] - q[o, 0]) * (q[b, 1] - q[o, 1]) - (q[a, 1] - q[o, 1]) * (q[b, 0] - q[o, 0])

    scale = float(np.ptp(q, axis=0).max()) ** 2
    lower, upper = [], []
    for i in order:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], i) <= 1e-12 * scale:
            lower.pop()
        lower.append(i)
    for i in reversed(order):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], i) <= 1e-12 * scale:
            upper.pop()
        upper.append(i)
    return np.asarray(lower[:-1] + upper[:-1], dtype=np.int64)


def convex_intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The intersection of two convex polygons (n, 2), (m, 2) (Sutherland-Hodgman: ``a`` clipped by each side
    of ``b``); (k, 2) in ``a``'s orientation, empty when they do not overlap."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    if polygon_area2(b) < 0:
        b = b[::-1]
    out = list(a)
    for i in range(len(b)):
        p, q = b[i], b[(i + 1) % len(b)]
        e = q - p
        src, out = out, []
        if not src:
            break
        for j in range(len(src)):
            c, d = src[j], src[(j + 1) % len(src)]
            fc = e[0] * (c[1] - p[1]) - e[1] * (c[0] - p[0])
            fd = e[0] * (d[1] - p[1]) - e[1] * (d[0] - p[0])
            if fc >= 0:
                out.append(c)
            if (fc >= 0) != (fd >= 0):
                out.append(c + (d - c) * (fc / (fc - fd)))
    return np.asarray(out, float).reshape(-1, 2)


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


# --- the scene of a target group ------------------------------------------------------------------
@dataclass(frozen=True)
class TargetScene:
    """What a target group shows.  ``id``: the preset's name (T1-T4) or ``custom``."""

    id: str
    shapes: tuple
    board: Material = BOARD_MATERIAL
    lights: tuple = (Light(),)
    ambient: float = 0.0  # constant environment: irradiance on the open board, x the group's irradiance_w_m2
    clutter: tuple = ()  # ``Clutter`` items in front of the board (raised planar shapes and boxes)
    #: the board's half width and height (a group's ``board_size_m`` / 2); the board is centred on the board frame
    board_half_size_m: tuple = BOARD_HALF_SIZE_M

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
        if tuple(self.board_half_size_m) != BOARD_HALF_SIZE_M:  # likewise: the default board keeps it
            out["board_half_size_m"] = list(self.board_half_size_m)
        return out


def _read_presets() -> dict:
    from importlib import resources

    from edgetruth.fileio import read_toml

    return read_toml(resources.files("edgetruth.assets") / "targets.toml")


def _load_presets() -> dict:
    """T1-T4, the checkerboard (and any other preset) from the shipped ``assets/targets.toml``: name ->
    (description, list of shape tables)."""
    return {name: (t.get("description", ""), t["shape"]) for name, t in _read_presets().items()}


PRESETS = _load_presets()
#: the preset that describes ``kind = "checkerboard"`` groups (``targets.Checkerboard``'s defaults)
CHECKERBOARD_PRESET = "checkerboard"


def checkerboard_preset() -> tuple[Shape, float]:
    """The shipped checkerboard preset: its catalogue shape (the dark squares, their material) and its
    white margin around the squares (``margin_m``, m)."""
    t = _read_presets()[CHECKERBOARD_PRESET]
    where = f"assets/targets.toml [{CHECKERBOARD_PRESET}]"
    if len(t["shape"]) != 1:
        raise InputError(f"{where}: shape must hold one checkerboard")
    shape = shape_from_dict(t["shape"][0], 0.13, f"{where} shape")
    if shape.type != "checkerboard" or shape.material.type != "diffuse" or shape.material.texture:
        raise InputError(f"{where}: shape must be a checkerboard of a diffuse, unprinted material (kind = "
                         "\"checkerboard\" renders matte squares)")
    return shape, float(t.get("margin_m", 0.0))


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
        if s.type not in ("rectangle", "circle") or len(PRESETS[name][1]) != 1:
            continue  # not a fixed-scene target (the checkerboard: kind = "checkerboard")
        m = s.material
        d = {"shape": "square" if s.type == "rectangle" else "circle", "material": m.label,
             "reflectance": m.albedo}
        if m.type == "roughplastic":
            d.update(alpha=m.alpha, eta=m.eta)
        out[name] = d
    return out


SCENE_GROUP_KEYS = ("shapes", "target_material", "board_material", "lights", "ambient", "clutter", "board_size_m")


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
            shapes[i] = replace(sh, material=with_texture_file(sh.material, base_dir, w))
    if "lights" in raw:
        if "light_position_m" in raw:
            raise InputError(f"{where}: lights and light_position_m: light_position_m moves the default light; "
                             "give the position in each light instead")
        lights = lights_from_list(g["lights"], f"{where} lights")
    else:
        lights = (Light(position_m=tuple(light_position_m)),)
    # a box stands on the prints: its base just in front of the top shape (nothing printed pokes through it)
    clutter = () if raw.get("clutter") is None else clutter_from_list(
        g["clutter"], size_m, f"{where} clutter", box_base_m=(len(shapes) + 1) * TARGET_STANDOFF_M)
    half = BOARD_HALF_SIZE_M
    if raw.get("board_size_m") is not None:
        half = (0.5 * float(g["board_size_m"][0]), 0.5 * float(g["board_size_m"][1]))
    for i, sh in enumerate(shapes):  # every print on the board: a shape past its edge would hang in the air
        xy = np.abs(sh.sample_points())
        if np.any(xy[:, 0] > half[0]) or np.any(xy[:, 1] > half[1]):
            raise InputError(f"{where}: shapes[{i}] ({sh.type} at {list(sh.offset_m)} m) reaches past the board "
                             f"({2 * half[0]:g} x {2 * half[1]:g} m, centred); enlarge board_size_m or move the shape")
    return TargetScene(id=sid, shapes=tuple(shapes), board=board, lights=lights, ambient=float(g.get("ambient", 0.0)),
                       clutter=clutter, board_half_size_m=half)

