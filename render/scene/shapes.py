"""The shape catalogue of the target scene: rectangles, circles, ellipses, rings and polygons on the board.

Pure data and geometry, no Mitsuba.  A ``Shape`` sits on the board at ``offset_m`` (board frame: x right,
y down from the board centre) turned by ``rotation_deg`` (from +x towards +y), printed flush: shape k
of a scene lies ``(k + 1) x TARGET_STANDOFF_M`` in front of the board, so a later shape covers an
earlier one.  A ring's hole shows the board (it covers what lies under it, like a disk with a white
centre).  Its outlines are straight sides (rectangle, polygon) or ellipses (circle, ellipse, ring: two);
``edgetruth.render.scene.outline.OutlineCurve`` carries them through the lens, and ``visible_intervals`` says
which parts of each outline are not covered by later shapes.

A shape's printed texture fills its bounding box in its own frame (``Shape.texture_frame``), turned and
moved with it.  Beside it: ``polygons`` (plane polygon geometry), ``clutter`` (raised shapes and boxes in front
of the board, their covers and shadows) and ``target_scene`` (what a target group shows; T1-T4 presets).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.scene.materials import Material
from edgetruth.render.scene.polygons import check_simple_polygon, point_in_polygon, rot
from edgetruth.render.schema import Key, parse_table


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
        return np.column_stack([a * np.cos(ang), b * np.sin(ang)]) @ rot(th).T + [cx, cy]

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
        return np.asarray(xy, float) @ rot(math.radians(self.rotation_deg)).T + np.asarray(self.offset_m)

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
            sq = np.array([[-h, -h], [h, -h], [h, h], [-h, h]]) @ rot(th).T  # TL, TR, BR, BL, turned
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
            q = (xy - np.asarray(self.offset_m, float)) @ rot(math.radians(self.rotation_deg))
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
            q = (xy - [cx, cy]) @ rot(th)
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


