"""The render spec's key tables: what ``[spec]``, ``[[group]]``, ``[design]`` and its factors and levels take
(``Key``: name, type, default, unit, meaning, range), and the choices they name.  ``spec.load_spec`` validates
against them and ``spec_doc`` writes docs/spec.md from them: one place for each key."""
from __future__ import annotations

from edgetruth.render.optics.camera import DEFAULT_CAMERA
from edgetruth.render.scene.charuco import CharucoBoard
from edgetruth.render.scene.mitsuba_scene import LIGHT_OFFSET_M, RenderSettings
from edgetruth.render.scene.pose import ROTATION_TOLERANCE
from edgetruth.render.scene.targets import TARGETS
from edgetruth.render.schema import REQUIRED, Key

KINDS = ("target", "checkerboard", "squares", "charuco", "circles_grid")
SAMPLERS = ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")
MAX_SPP = 1 << 16
MAX_IMAGES = 10_000_000
DEFAULT_IRRADIANCE_W_M2 = 1.2  # the white board centre at ~60 % of the range above the black level at 0 dB

SPEC_KEYS = [
    Key("name", "name", None, "", "spec name (names the output directory and seeds every image); "
        "default: the file name"),
    Key("description", "str", "", "", "free text"),
    Key("camera", "str", DEFAULT_CAMERA, "", "a shipped camera name or a camera TOML path (relative to the spec's "
        "folder)"),
    Key("camera_scale", "int", 1, "", "binning: the camera with camera_scale x fewer pixels per side (same field "
        "of view, pitch x camera_scale)", 1, 64),
    Key("spp", "int", RenderSettings.spp, "samples/px", "Monte-Carlo samples per pixel (a power of two, of "
        "four for multijitter and stratified: byte-identical renders whatever the thread count)", 1, MAX_SPP),
    Key("edge_spp", "int", RenderSettings.edge_spp, "samples/px", "samples per pixel near a target's outline "
        "(within the PSF, defocus and motion reach; the rest of the frame uses spp; a power of two, of four for multijitter and stratified); 0 = spp "
        "everywhere", 0, MAX_SPP),
    Key("edge_mode", "str", "frame", "", "target images: path = the frame path-traced at spp and the edge band at "
        "edge_spp (the reference); analytic = the board and the target's material rendered without an edge at "
        "edge_spp and composited with the exact lens-weighted coverage (no Monte-Carlo noise from the edge; preset "
        "targets, static camera; docs/optics.md); frame = that composite over every pixel, the board and the "
        "target's material rendered at edge_spp on every shading_step_px-th pixel and interpolated (no full-frame "
        "render: target images cost a fraction). Not given: frame where it is valid (preset targets T1..T4, a "
        "static camera), else path, said in one line on stderr", choices=("path", "analytic", "frame")),
    Key("board_mode", "str", "frame", "", "board images (checkerboard, squares): path = the full frame path-traced "
        "(the reference); frame = the plate's shading rendered at the board's spp on every shading_step_px-th pixel "
        "and composited with the plate's and the squares' exact lens-weighted coverage (no Monte-Carlo noise at "
        "edges or in the squares; flat boards, static camera; docs/optics.md). Not given: frame where it is valid, "
        "else path, said in one line on stderr", choices=("path", "frame")),
    Key("shading_step_px", "int", RenderSettings.shading_step_px, "px", "edge_mode = \"frame\" and board_mode = "
        "\"frame\": the spacing of the shading grid's nodes", 2, 256),
    Key("checkerboard_spp", "int", 0, "samples/px", "samples per pixel of the checkerboard images (their corners "
        "are edges, and boards have no edge band; a power of two, of four for multijitter and stratified); "
        "0 = spp", 0, MAX_SPP),
    Key("sampler", "str", RenderSettings.sampler, "", "Mitsuba sampler (orthogonal is not bit-reproducible in "
        "Mitsuba 3.9: its renders differ in the last bit from run to run)", choices=SAMPLERS),
    Key("target_size_m", "float", 0.13, "m", "target side (square) or diameter (circle)", 1e-3, 10.0),
    Key("checkerboard", "table", {}, "", "the calibration board {cols, rows, square_m, margin_m}"),
    Key("squares", "table", {}, "", "the board of dark squares of kind = \"squares\" groups {model, "
        "model_unit_m | rows, cols, side_m, pitch_m; margin_m, plate_size_m, square_reflectance, "
        "board_reflectance}"),
    Key("circles_grid", "table", {}, "", "the circle grid of kind = \"circles_grid\" groups {cols, rows, spacing_m, "
        "diameter_m, asymmetric, margin_m}: dark circles on a white plate in OpenCV's findCirclesGrid layout "
        "(edgetruth.render.scene.circles_grid)"),
    Key("charuco", "table", {}, "", "the ChArUco board of kind = \"charuco\" groups {cols, rows, square_m, "
        "marker_m, dictionary, legacy, margin_m, square_reflectance, board_reflectance} (OpenCV's CharucoBoard)"),
]
GROUP_KEYS = [
    Key("name", "name", REQUIRED, "", "group name (unique in the spec; part of every image name)"),
    Key("kind", "str", "target", "", "what the images show: a target on a board, a checkerboard, a board "
        "of dark squares ([spec] squares), a ChArUco board ([spec] charuco) or a circle grid ([spec] circles_grid)",
        choices=KINDS),
    Key("target", "str", "T1", "", "target id (kind = target)", choices=tuple(TARGETS)),
    Key("count", "int", 1, "images", "images over distance_range_cm (one per equal sub-interval)", 1, MAX_IMAGES),
    Key("distance_range_cm", "range2", (150.0, 150.0), "cm", "[near, far] distance of the board centre", 1.0, 1e5),
    Key("distance_intervals_cm", "ranges", None, "cm", "[[near, far], ...]: count_per_interval images per "
        "interval (replaces count and distance_range_cm)", 1.0, 1e5),
    Key("count_per_interval", "int", 10, "images", "images per distance interval", 1, MAX_IMAGES),
    Key("lateral_fraction", "float", 0.0, "", "lateral offset, as a fraction of the room left in the field of view",
        0.0, 1.0),
    Key("tilt_max_deg", "float", 0.0, "deg", "tilts about the board's x and y axes drawn from U(-t, t)", 0.0, 80.0),
    Key("roll_max_deg", "float", 0.0, "deg", "roll about the optical axis drawn from U(-r, r)", 0.0, 180.0),
    Key("irradiance_w_m2", "float", DEFAULT_IRRADIANCE_W_M2, "W/m^2", "irradiance at the board centre "
        "(sets the light's power)", 1e-9, 1e6),
    Key("sensor", "table", {}, "", "sensor overrides for this group (any [sensor] key)"),
    Key("camera", "table", {}, "", "camera overrides for this group (per-group camera keys only)"),
    Key("poses", "tables", None, "", "explicit poses [{R = [[r11, r12, r13], [...], [...]], t = [tx, ty, tz]}, "
        "...]: one image per pose, instead of count, distances, lateral_fraction, tilts and roll; "
        "X_cam = R X_board + t (OpenCV camera frame); the board frame: kind squares: the model's frame "
        "([spec] squares), kind charuco: OpenCV's board frame (origin at its top-left outer corner), kind "
        "circles_grid: the frame of OpenCV's object points (circle 0 at its origin), else centred on the board "
        "(x right, y down, z into it); R must be a rotation "
        f"(R^T R = I within {ROTATION_TOLERANCE:g}, det +1; the nearest rotation is used); t in pose_unit_m"),
    Key("pose_unit_m", "float", 1.0, "m", "unit of the explicit poses' t (1: metres; 0.0254: inches)", 1e-9, 1e3),
    Key("board_bend_mm", "floats", None, "mm", "kind = squares or checkerboard: the board curled, its height "
        "(into the board) s * sum c_k m_k(x / s, y / s) over board coordinates centred on the printed squares, "
        "s = half the larger side of their bounding box; 3 coefficients (x^2, xy, y^2: a cylinder, dome or "
        "saddle) or 7 (and x^3, x^2 y, x y^2, y^3), each the monomial's height at the squares' edge "
        "(edgetruth.render.scene.bend; the bend check of edgetruth calibrate fits the same terms); the "
        "plate and squares are then fine meshes, the truth lies on the curled surface", -50.0, 50.0,
        check=lambda v: None if len(v) in (3, 7) else "give 3 coefficients (x^2, xy, y^2) or 7 (and x^3, "
        "x^2 y, x y^2, y^3)"),
    Key("light_position_m", "vec3", tuple(float(v) for v in LIGHT_OFFSET_M), "m", "where the square area light "
        "sits (camera frame), aimed at the board centre; z < 0 (behind the image plane: never in view)",
        -100.0, 100.0, check=lambda v: None if v[2] < 0 else "z must be < 0 (behind the camera's image plane), "
        "or the light could stand in view or shade the board"),
    # the scene of a target group (edgetruth.render.scene.shapes): any key here renders the group's own scene
    Key("shapes", "tables", None, "", "kind = target: the shapes on the board [{type, offset_m, rotation_deg, "
        "size keys, material}, ...] (\"Shapes\" below), replacing the target preset's; shape 0 is the ranged "
        "target, a later shape covers earlier ones"),
    Key("target_material", "table", {}, "", "kind = target: material keys {type, albedo, alpha, eta, "
        "specular_reflectance, label} over shape 0's material (\"Materials\" below); in a [design], levels of "
        "two factors merge (albedo x gloss)"),
    Key("board_material", "table", {}, "", "kind = target: the board's material keys (default diffuse, albedo "
        "0.8)"),
    Key("lights", "tables", None, "", "kind = target: the lights [{type, position_m, aim_board_m, size_m, share, "
        "cutoff_deg, beam_deg}, ...] (\"Lights\" below), replacing the default square area light"),
    Key("clutter", "tables", None, "", "kind = target: planar shapes held in front of the board, parallel to it "
        "[{type (rectangle, circle, ellipse, polygon or grid), offset_m, rotation_deg, size keys, material, "
        "raised_m (how far in front of the board, >= 0.001 m)}, ...], and boxes standing on it [{type = \"box\", "
        "size_m = [x, y, z], offset_m, rotation_deg, material}] (\"Clutter boxes\" below): they hide what lies "
        "behind them and cast shadows on the board; the truth gives their outlines (a box: its silhouette) "
        "and, per light, their shadows' outlines"),
    Key("ambient", "float", 0.0, "", "kind = target: a constant environment light giving ambient x "
        "irradiance_w_m2 on the open board (adds Monte-Carlo noise: it is sampled over the sphere)", 0.0, 100.0),
    Key("board_size_m", "vec2", None, "m", "kind = target: [width, height] of the board, centred on the board "
        "frame (default 3.6 x 3.0 m: it fills the frame at 3 m); every shape must lie on it; beyond it the "
        "background is black; the truth records board.half_size_m and, when set, the board's outline", 1e-3, 100.0),
]


POSE_KEYS = ("count", "distance_range_cm", "distance_intervals_cm", "count_per_interval", "lateral_fraction",
             "tilt_max_deg", "roll_max_deg")
#: a group's own keys that a [design] does not take (explicit poses and the light's place are per group)
GROUP_ONLY_KEYS = ("poses", "pose_unit_m", "light_position_m")
DESIGN_MODES = ("one_at_a_time", "full")
DESIGN_KEYS = [
    Key("kind", "str", "target", "", "what the images show", choices=KINDS),
    Key("mode", "str", "one_at_a_time", "", "cells: one_at_a_time = the base cell (every factor's first level) "
        "plus each other level of one factor at a time; full = every combination", choices=DESIGN_MODES),
    *[k for k in GROUP_KEYS if k.name in POSE_KEYS],
    Key("factor", "tables", REQUIRED, "", "[[design.factor]] tables: name + levels"),
]
FACTOR_KEYS = [
    Key("name", "name", REQUIRED, "", "factor name (e.g. illumination, target)"),
    Key("levels", "tables", REQUIRED, "", "[{name = ..., <group keys>}, ...]: each level sets any [[group]] key "
        "except the pose keys (target, irradiance_w_m2, sensor, camera, ...)"),
]
#: the boards a level's ``kind`` may name: cells of different boards share pose slots (a "which pattern?" design)
BOARD_KINDS = ("checkerboard", "squares", "charuco", "circles_grid")
#: keys a level may set: the group's own keys except its name and the pose keys (shared by every cell), and a
#: board kind (every cell a board, drawn on the same slots: the board centre's pose is the same in each)
LEVEL_KEYS = [Key("name", "name", REQUIRED, "", "level name (part of the cell name)"),
              Key("kind", "str", None, "", "a board kind (the design's cells then compare boards on the same pose "
                  "slots; every cell must be a board)", choices=BOARD_KINDS)] + [
    k for k in GROUP_KEYS if k.name not in POSE_KEYS and k.name not in ("name", "kind") + GROUP_ONLY_KEYS]
