"""A ``TargetScene`` is what a target group shows: its shapes (shape 0 is the ranged target), the board's
material, its lights, an ambient term and its clutter.  T1-T4 and the checkerboard are presets of it, read
from the shipped ``assets/targets.toml``; ``scene_from_group`` reads a spec's group."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.scene.clutter import clutter_from_list
from edgetruth.render.scene.lights import Light
from edgetruth.render.scene.materials import BOARD_MATERIAL, Material
from edgetruth.render.scene.shapes import BOARD_HALF_SIZE_M, MAX_SHAPES, Shape, TARGET_STANDOFF_M, shape_from_dict


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

