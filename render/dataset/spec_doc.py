"""``docs/spec.md``, generated from the key tables the loader checks against (so the two cannot drift).

    python -m edgetruth.render.dataset.spec_doc > docs/spec.md     # tests/render/dataset/test_spec.py checks it is current
"""
from __future__ import annotations

from edgetruth.render.optics.camera import CAMERA_KEYS, DISTORTION_KEYS
from edgetruth.render.schema import REQUIRED, Key
from edgetruth.render.sensor.linear_model import SENSOR_KEYS
from edgetruth.render.dataset.spec import DESIGN_KEYS, FACTOR_KEYS, GROUP_KEYS, LEVEL_KEYS, SPEC_KEYS
from edgetruth.render.scene.circles_grid import CIRCLES_GRID_KEYS
from edgetruth.render.scene.charuco import CHARUCO_KEYS
from edgetruth.render.scene.targets import CHECKERBOARD_KEYS, SQUARES_KEYS, TARGETS

INTRO = """# Render specs and cameras

A **spec** (TOML) declares a dataset: `edgetruth render SPEC -o DIR` renders every image
of it, each a pure function of (spec, index).  `SPEC` is a shipped name
({SHIPPED}) or a path.  A spec has a `[spec]` table, an
optional `[sensor]` table, `[[group]]` tables (each draws its own poses) and/or a
`[design]` (paired cells on shared pose slots); a **camera** is a TOML file
with a `[camera]` table, named by `[spec] camera` (a shipped name, or a path relative to
the spec's own folder).  Every key is checked when the spec loads (type, range, choices,
unknown keys): a bad value is one error line naming the file, the table, the key and the
fix, before anything renders.

```toml
[spec]
name = "mine"
camera = "my_camera.toml"       # next to this file; or "default"
spp = 64

[sensor]
gain_db = 6.0

[[group]]
name = "near"
target = "T2"
distance_range_cm = [60, 120]
count = 10
camera = { f_number = 2.8 }     # per-group camera override (keys marked "per group")
sensor = { exposure_s = 0.02 }  # per-group sensor override (any [sensor] key)

[[group]]
name = "boards"
kind = "checkerboard"
distance_range_cm = [55, 110]
count = 15
tilt_max_deg = 35
```

**Render modes when a spec names none.** Target images render with `edge_mode = "frame"` (every pixel
composited from the exact lens-weighted coverage of the outline and the shading rendered on a grid: no
Monte-Carlo noise at the edges, and no full-frame render) wherever it is valid: every target group a preset
target (T1..T4) seen by a static camera.  Board images (checkerboard, squares) render with `board_mode = "frame"`
wherever every board group is flat and seen by a static camera.  A spec outside that scope -- a target group
with a scene of its own (shapes, materials, lights, clutter), a moving camera, a curled board -- renders that
kind with `"path"`, the path tracer, and says so in one line on stderr (once per spec) naming the group, the
reason and how to silence it.  A spec that names a mode renders with it (`"path"` is the Monte-Carlo reference;
a named `"frame"` outside its scope is refused), and a mode no image of the spec uses stays `"path"`, so the
spec's identity is unchanged.  Every shipped spec names the modes its images use.  Each image's JSON records
the mode that made it (docs/formats.md, `render`).  docs/optics.md has the composites' checks against the
path tracer.

Units are in the key names or the tables below; lengths are metres unless a name says
otherwise; image coordinates follow OpenCV (pixel centres at integers).
This file is generated from the loader's key tables by `python -m edgetruth.render.dataset.spec_doc`.
"""


def _default(k: Key) -> str:
    if k.default is REQUIRED:
        return "required"
    if k.default is None:
        return "—"
    if isinstance(k.default, dict) and not k.default:
        return "{}"
    if isinstance(k.default, tuple):
        return "[" + ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in k.default) + "]"
    if isinstance(k.default, str):
        return f'"{k.default}"' if k.default else '""'
    if isinstance(k.default, bool):
        return str(k.default).lower()
    if isinstance(k.default, float):
        return f"{k.default:g}"
    return str(k.default)


def table(keys: list[Key], per_group_column: bool = False) -> str:
    head = ["key", "type", "unit", "default", "range / choices", "meaning"] + (["per group"] if per_group_column else [])
    rows = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for k in keys:
        cells = [f"`{k.name}`", k.type, k.unit or "", _default(k), k.describe_range(), k.meaning]
        if per_group_column:
            cells.append("yes" if k.per_group else "")
        rows.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(rows)


def scene_section() -> list[str]:
    """The target scene's own keys: shapes, materials, lights (``edgetruth.render.scene.shapes``)."""
    from edgetruth.render.scene.lights import LIGHT_KEYS
    from edgetruth.render.scene.materials import MATERIAL_KEYS
    from edgetruth.render.scene.clutter import BOX_KEYS
    from edgetruth.render.scene.shapes import SHAPE_KEYS

    return [
        "### The target scene: shapes, materials, lights", "",
        "T1-T4 are presets of a catalogue of shapes (the shipped `assets/targets.toml`).  A `kind = \"target\"` "
        "group that sets any of `shapes`, `target_material`, `board_material`, `lights` or `ambient` renders "
        "its own scene (a group that sets none renders the presets' fixed scene, byte for byte as before).  "
        "Each of these keys may also be a `[design]` level's, so a factor can sweep albedo, gloss or the "
        "light; two factors' `target_material` tables merge (albedo x gloss).  Cells that differ in them "
        "are separate radiance units.", "",
        "```toml", "[[group]]", 'name = "mixed"',
        'lights = [ { type = "area", position_m = [0, -0.15, -0.05] },',
        '           { type = "spot", position_m = [0.5, 0, -0.05], aim_board_m = [0.1, 0], share = 0.3 } ]',
        "ambient = 0.05", "", "[[group.shapes]]      # shape 0: the ranged target", 'type = "rectangle"',
        "width_m = 0.12", "height_m = 0.08", "rotation_deg = 15", "", "[[group.shapes]]", 'type = "ring"',
        "offset_m = [0.15, 0]", "outer_diameter_m = 0.1", "inner_diameter_m = 0.05",
        'material = { type = "roughplastic", albedo = 0.03, alpha = 0.1 }', "", "[[group.shapes]]",
        'type = "polygon"', "offset_m = [-0.15, 0]", "vertices_m = [[-0.04, -0.03], [0.05, 0], [-0.04, 0.03]]",
        "```", "",
        "**Shapes** (`shapes = [...]`): shape 0 is the ranged target (the ground truth's `target` and "
        "`outline`); every shape lies on the board at `offset_m`, turned by `rotation_deg`, shape k "
        "(k + 1) x 10 um in front of the board, so a later shape covers an earlier one; a ring's hole shows "
        "the board.  Sizes default to `[spec] target_size_m`.  The ground truth lists every shape under "
        "`shapes`: each outline (a ring has two) as its exact distorted curve (straight sides and conics "
        "through the lens), its corners, and the parts later shapes leave visible "
        "(`visible_intervals`, `visible_polylines_distorted_px`, `occlusion_points_distorted_px`; the "
        "JSON's `shapes_meaning` says how to read them).", "",
        "A `checkerboard` shape is `rows` x `cols` squares of `square_m` centred on `offset_m`: the dark "
        "squares (row + col even, row 0 col 0 at the top-left of the unturned board) are printed in its "
        "`material`, the light squares are not printed (they show the board).  Each dark square is its own "
        "closed outline `r<row>c<col>` (corners top-left, top-right, bottom-right, bottom-left); where two "
        "dark squares touch at a corner both outlines pass through it, so the outline is split there per "
        "square.  Its `inner_corners` (where four squares meet) come in the shape's truth, row-major with "
        "x fastest (`cv2.findChessboardCorners`' order), distorted and undistorted.  The shipped preset "
        "`assets/targets.toml [checkerboard]` is the board of `kind = \"checkerboard\"` groups.", "",
        "`board_size_m = [w, h]` sets the board's size (default 3.6 x 3.0 m); beyond it the background is black (with "
        "`ambient`: its radiance).  Every shape must lie on the board.  The truth's `board.half_size_m` records it and, when "
        "set, `board.outline` gives the board's own edge (its exact distorted curve); the reader's "
        "`Sample.outline` counts it as a visible edge (shape index -1, the board's side positive).", "",
        "```toml", "[[group]]", 'name = "small_board"', "board_size_m = [0.5, 0.4]",
        'shapes = [{ type = "checkerboard", rows = 7, cols = 10, square_m = 0.03, rotation_deg = 10 }]', "```", "",
        table(SHAPE_KEYS), "",
        "**Materials** (a shape's `material`, `target_material`, `board_material`): achromatic; keys that a "
        "type does not use are refused.  `target_material` changes only the keys it gives over shape 0's "
        "material (a preset's or your shape's).", "",
        table(MATERIAL_KEYS), "",
        "**Lights** (`lights = [...]`, replacing the default 5 cm area light above the camera; "
        "`light_position_m` moves only the default one).  Each light's power is the irradiance it gives at "
        "its aim point, `share` x the group's `irradiance_w_m2`; `ambient` adds a constant environment "
        "giving `ambient` x `irradiance_w_m2` on the open board.  With several lights the direct integrator "
        "picks one per sample (more Monte-Carlo noise per spp).  The ground truth's `illumination` records "
        "every light, its emission, and the irradiance it gives at the board centre and at each shape's "
        "centre, and the range of the total irradiance on the target's outline (its non-uniformity, %).", "",
        table(LIGHT_KEYS), "",
        "**Clutter boxes** (an item `{ type = \"box\", ... }` of `clutter = [...]`): a cuboid standing on the "
        "board, on top of its printed shapes.  The ground truth gives its silhouette seen from the camera "
        "(`clutter[].outlines[0]`, named `silhouette`: a polygon of its corners, `vertices_board_m`, each "
        "side a straight 3-D edge through the lens), the parts of it that nearer clutter leaves visible, "
        "and, per light, its shadow on the board (exact for point and spot lights: the convex hull of its "
        "corners' projections from the light).", "",
        table(BOX_KEYS), ""]


def spec_markdown() -> str:
    targets = "\n".join(f"| `{t}` | {d['shape']} | {d['material'].replace('_', ' ')} | {d['reflectance']} |"
                        for t, d in TARGETS.items())
    from edgetruth.resources import shipped_spec_names

    shipped = ", ".join(f"`{n}`" for n in shipped_spec_names())
    parts = [INTRO.replace("{SHIPPED}", shipped),
             "## `[spec]`", "", table(SPEC_KEYS), "",
             "### `[spec] checkerboard = {...}`", "",
             "The board of `kind = \"checkerboard\"` groups: the catalogue's `checkerboard` shape (\"Shapes\" "
             "below) on a white plate `margin_m` wider than its squares.  Its defaults are the shipped preset "
             "`assets/targets.toml [checkerboard]` (10 x 7 squares of 30 mm, black matte 0.04); the mesh is that "
             "shape's dark squares, bit for bit.", "", table(CHECKERBOARD_KEYS), "",
             "### `[spec] squares = {...}` (or a `[spec.squares]` table)", "",
             "The board of `kind = \"squares\"` groups: dark squares (any convex quads) printed flush on a "
             "white plate, rendered like the checkerboard (one mesh on the plate).  The squares come from a "
             "model file (Zhang's `Model.txt` layout: one square per line, x y of its 4 corners, in "
             "`model_unit_m`) or from a pattern of `rows` x `cols` squares of `side_m` every `pitch_m` "
             "(row-major from the top-left square, model origin at its top-left corner).  The model's frame "
             "has x right, y down on the board and z into it (the frame explicit poses map); sampled poses "
             "place the centre of the squares' bounding box.  The ground truth lists every square's corners "
             "(model order) and its exact distorted outline (docs/formats.md).", "",
             table(SQUARES_KEYS), "",
             "### `[spec] circles_grid = {...}`", "",
             "The board of `kind = \"circles_grid\"` groups: dark circles (black matte, 0.04) printed flush on a "
             "white plate, in OpenCV's `cv2.findCirclesGrid` layout: `cols` circles in each of `rows` rows "
             "(its patternSize), symmetric (circle (row i, column j) at (j s, i s)) or asymmetric (at "
             "((2 j + i % 2) s, i s), OpenCV's calibration sample: s is the row spacing and half the distance "
             "between neighbours in a row), s = `spacing_m`.  Explicit poses map the object points' frame "
             "(circle 0 at the origin); sampled poses place the centre of the circles' bounding box.  "
             "`board_mode = \"frame\"` covers each circle's exact outline; `\"path\"` path-traces each as a "
             "258-gon of its area (within 1e-4 of its radius).  The truth gives per circle the image of its "
             "centre, its pinhole image ellipse's centre (the perspective bias) and its exact distorted outline "
             "(docs/formats.md, docs/patterns.md).", "",
             table(CIRCLES_GRID_KEYS), "",
             "### `[spec] charuco = {...}`", "",
             "The board of `kind = \"charuco\"` groups: OpenCV's ChArUco board, "
             "`cv2.aruco.CharucoBoard((cols, rows), square_m, marker_m, cv2.aruco.getPredefinedDictionary("
             "dictionary))` with `setLegacyPattern(legacy)`: a chessboard of `cols` x `rows` squares whose white "
             "squares each hold one ArUco marker (ids 0, 1, ... row-major from the top-left; `marker_m` includes "
             "the marker's one-cell black border).  Which squares are dark, where each marker sits and its "
             "bitmap are read from OpenCV's own board and dictionary (`Dictionary.generateImageMarker`), so a "
             "detector sees what it expects: the rendered board is OpenCV's `generateImage`, pixel for pixel, at "
             "any whole number of pixels per marker cell.  Everything dark is a union of axis-aligned squares "
             "in the board frame, so the board renders as a board of dark squares with exact edges: the "
             "chessboard's dark squares and each marker's dark cells merged into rectangles (runs of a row, "
             "stacked where the rows below repeat them; `edgetruth.render.scene.charuco`), printed flush on "
             "a white plate `margin_m` wider than the squares.  The board frame is OpenCV's: origin at the "
             "board's top-left outer corner, x right, y down, z into the board (the frame explicit poses map; "
             "sampled poses place the board's centre).  The ground truth lists every ChArUco corner and every "
             "marker's four corners with their ids (docs/formats.md).  `edgetruth calibrate --pattern "
             "charuco:COLSxROWS:DICT` calibrates from such boards (docs/board.md).", "",
             table(CHARUCO_KEYS), "",
             "## `[[group]]`", "",
             "A group's images are spread over its distances (one per equal sub-interval, uniform inside it); "
             "lateral offset, tilts and roll are drawn per image from the image's seed, and redrawn "
             "(deterministically) until the board's outline lies inside the image.", "",
             table(GROUP_KEYS), "",
             "Targets (`target`):", "", "| id | shape | material | Lambertian albedo |", "|---|---|---|---|", targets, "",
             *scene_section(),
             "### Explicit poses", "",
             "A group may list its poses instead of drawing them (one image per pose, in order): each is a "
             "rotation `R` (3 x 3, by rows) and a translation `t` (in `pose_unit_m`) with "
             "X_cam = R X_board + t in the OpenCV camera frame (x right, y down, z forward).  For "
             "`kind = \"squares\"` X_board is the model's frame (e.g. a published calibration's extrinsics "
             "with its model points); for `kind = \"charuco\"` OpenCV's board frame (origin at its top-left outer "
             "corner, as `cv2.aruco` returns poses); for targets and checkerboards the board frame centred on "
             "the board.  "
             "`R` is checked to be a rotation and replaced by the nearest one (SVD); the board must lie in "
             "front of the camera, and a target's outline in the image.  Each image's ground truth records "
             "the pose it used (`pose`; for squares also `squares.pose_model`).", "",
             "```toml", "[[group]]", 'name = "zhang"', 'kind = "squares"', "pose_unit_m = 0.0254   # t in inches",
             "", "[[group.poses]]", "R = [[0.992759, -0.026319, 0.117201], [0.0139247, 0.994339, 0.105341], "
             "[-0.11931, -0.102947, 0.987505]]", "t = [-3.84019, 3.65164, 12.791]", "```", "",
             "## `[design]`: a paired design", "",
             "Every cell of a design renders the *same pose slots* (slot k has one seed: the same distance, "
             "offset, tilt and roll in every cell), so levels are compared on the same poses.  A cell is one "
             "level of every factor; `mode` chooses the cells; a cell's images are named "
             "`NNNN_<level>_<level>...`.  Cells that differ only in light power (`irradiance_w_m2`) and "
             "sensor settings form one *radiance unit*: each slot is rendered once, at the unit's first "
             "irradiance, and scaled for the others (light transport is linear in emitted power; bit-exact "
             "for power-of-two steps).  Sensor noise stays independent per image.  A level may also set a board `kind` (checkerboard, squares, charuco, circles_grid): the cells then show different boards on the same slots, each slot's pose drawn so that every cell's board fits, so the board centre's pose is the same in each (scenes/which_pattern.toml: `edgetruth study pattern`).", "",
             "```toml", "[design]", "distance_intervals_cm = [[50, 100], [100, 150]]", "count_per_interval = 10",
             "tilt_max_deg = 3", "", "[[design.factor]]", 'name = "snr"',
             'levels = [ { name = "G1", irradiance_w_m2 = 1.75 },',
             '           { name = "G2", irradiance_w_m2 = 0.875, sensor = { gain_db = 6.0206 } } ]', "",
             "[[design.factor]]", 'name = "target"',
             'levels = [ { name = "T1", target = "T1" }, { name = "T2", target = "T2" } ]', "```", "",
             table(DESIGN_KEYS), "",
             "### `[[design.factor]]`", "", table(FACTOR_KEYS), "",
             "### a level (one table of a factor's `levels`)", "", table(LEVEL_KEYS), "",
             "## `[sensor]` (and a group's `sensor = {...}`)", "",
             "EMVA 1288 linear model: electrons = QE x photons (Poisson), + dark noise, clipped at the full "
             "well, x gain K = K0 10^(G/20) DN/e-, + black level, rounded and clipped to 2^bits - 1.", "",
             "Fixed-pattern noise (EMVA 1288 spatial non-uniformity; all off by default) is the camera's: drawn "
             "once from `fpn_seed` over the camera's frame, the same in every image whatever its seed.  PRNU "
             "scales each pixel's photo-electrons before shot noise (electrons = Poisson(QE x photons x "
             "(1 + prnu_pct/100 z_g) + hot dark current)); DSNU adds dsnu_e z_d electrons after the full well "
             "(z_g, z_d: standard normal maps set to mean 0, SD 1 over the frame), so EMVA 1288's DSNU1288 and "
             "PRNU1288 measure `dsnu_e` and `prnu_pct`; dead pixels read the black level.  Every image's ground "
             "truth records it under `fixed_pattern`: `dsnu_e` and `prnu_pct` over that image's pixels, "
             "`fpn_seed`, `origin_xy` (the image's top-left in the frame), `hot_pixels` and `dead_pixels` "
             "(`count`, and `xy`: [column, row] of each), `model` (docs/optics.md).", "",
             "Fewer output levels (off by default; 8-bit outputs only, applied last to the 8-bit image; no random "
             "numbers): `output_levels = N` maps each pixel to the nearest of N gray levels round(255 k / (N - 1)); "
             "`output_levels_rgb = [Nr, Ng, Nb]` writes the gray image through an RGB palette of that many levels "
             "per channel and reads it back as the rounded BT.601 luma (a gray photo saved as a 256-colour 3-3-2 "
             "palette image is `[8, 8, 4]`).  `output_dither = \"floyd_steinberg\"` diffuses each pixel's error "
             "(7/16 right, 3/16 down-left, 5/16 down, 1/16 down-right, raster order, each channel on its own) "
             "instead of rounding to the nearest level: the local mean is kept, the error becomes high-frequency "
             "noise.  The ground truth's `image.quantisation` states the levels and the dither.  To reduce only "
             "some images, put the keys in their groups' `sensor = {...}`.", "",
             table(SENSOR_KEYS), "",
             "## Camera TOML: `[camera]`", "",
             "Keys marked *per group* may be overridden by a group's `camera = {...}`; the others fix the "
             "intrinsics of the whole spec (one calibration).  By default fx = fy = f / pitch and the "
             "principal point is the image centre; `fx_px`, `fy_px`, `cx_px`, `cy_px` state a calibrated K "
             "instead (skew is not modelled; `assets/cameras/zhang1998.toml` states Zhang's).  The renderer "
             "and `Camera.project` use the same K and distortion (OpenCV's model).  `aberration_sigma_y_um` makes "
             "the Gaussian aberration elliptical (sigma along y; `aberration_sigma_um` along x), sampled as "
             "exactly as the isotropic one (docs/optics.md).", "",
             table(CAMERA_KEYS, per_group_column=True), "",
             "### `[camera.distortion]`", "", table(DISTORTION_KEYS), ""]
    return "\n".join(parts)


if __name__ == "__main__":  # pragma: no cover
    print(spec_markdown(), end="")
