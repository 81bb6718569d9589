"""Materials of the targets and the board: diffuse albedo, rough plastic, rough conductor.

A ``Material`` is pure data (frozen, hashable: it keys the loaded scenes), read from a spec's
``material = {...}`` tables, written into the ground truth and turned into a Mitsuba BSDF dict.
Every material is achromatic (R = G = B), as the renderer keeps one channel.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, fields, replace
from pathlib import Path

from edgetruth.errors import InputError
from edgetruth.render.schema import Key, parse_table

MATERIAL_TYPES = ("diffuse", "roughplastic", "roughconductor")
#: a printed texture's largest side (px): a few times the finest print the camera can resolve
MAX_TEXTURE_PX = 8192
#: the keys each material type uses (the others are refused when given)
_USES = {"diffuse": ("albedo", "texture"), "roughplastic": ("albedo", "alpha", "eta"),
         "roughconductor": ("alpha", "specular_reflectance")}


@dataclass(frozen=True)
class Material:
    """``type``: diffuse (Lambertian ``albedo``), roughplastic (GGX ``alpha``, interior IOR ``eta``, diffuse
    ``albedo`` under a dielectric coat) or roughconductor (GGX ``alpha``, achromatic mirror-like metal of
    ``specular_reflectance``)."""

    type: str = "diffuse"
    albedo: float = 0.04
    alpha: float = 0.15
    eta: float = 1.5
    specular_reflectance: float = 1.0
    label: str = ""
    #: diffuse only: an image printed on the surface (any shape, over its bounding box, or the board), its
    #: gray level times ``albedo``; the absolute path and its SHA-256 once the spec is loaded
    #: (``with_texture_file``)
    texture: str = ""
    texture_sha256: str = ""

    def to_bsdf(self, uv_map: tuple | None = None) -> dict:
        """The Mitsuba BSDF dict (the same dicts the fixed T1-T4 scene used).  ``uv_map`` places a texture on a
        primitive that does not carry the whole image in its own uv square: ("rect", m) for a Mitsuba
        rectangle or a mesh with texture coordinates, ("polar", m) for a disk (whose uv is polar: radius,
        angle / 2 pi), m = (u0, ux, uy, v0, vx, vy) the texture coordinates u = u0 + ux x + uy y,
        v = v0 + vx x + vy y of its local point (x, y) in [-1, 1]^2 (a mesh's own texture coordinates: the
        identity, ("rect", (0.5, 0.5, 0, 0.5, 0, 0.5))); None: the image over the primitive's uv square (a
        rectangle shape, the board)."""
        if self.type == "diffuse" and self.texture:
            import mitsuba as mi

            # nearest texel: the print's texels are squares with sharp edges (the ground truth's placement)
            data = (self.albedo * texture_levels(self.texture, self.texture_sha256))[::-1, :, None]
            # the placed prints hand Mitsuba a Bitmap (its tensor form makes nanobind print failed overloads when
            # loaded on its own); the rectangle's and the board's keep the tensor (their renders unchanged)
            image = {"bitmap": mi.Bitmap(data.copy())} if uv_map is not None else {"data": mi.TensorXf(data.copy())}
            bitmap = {"type": "bitmap", **image, "raw": True, "filter_type": "nearest", "wrap_mode": "clamp"}
            if uv_map is not None and uv_map[0] == "rect":  # rectangle uv (x + 1) / 2, (y + 1) / 2
                u0, ux, uy, v0, vx, vy = uv_map[1]
                bitmap["to_uv"] = mi.ScalarTransform3f(mi.ScalarMatrix3f(
                    [[2 * ux, 2 * uy, u0 - ux - uy], [2 * vx, 2 * vy, v0 - vx - vy], [0.0, 0.0, 1.0]]))
            elif uv_map is not None:
                bitmap = {"type": polar_print_plugin(), "texture": mi.load_dict(bitmap),
                          **dict(zip(("u0", "ux", "uy", "v0", "vx", "vy"), map(float, uv_map[1])))}
            return {"type": "diffuse", "reflectance": bitmap}
        if self.type == "diffuse":
            return {"type": "diffuse", "reflectance": float(self.albedo)}
        if self.type == "roughplastic":
            return {"type": "roughplastic", "distribution": "ggx", "alpha": float(self.alpha),
                    "int_ior": float(self.eta), "diffuse_reflectance": float(self.albedo)}
        # material "none": a perfect conductor scaled by specular_reflectance (achromatic; a named metal
        # such as "Al" would give R != G != B)
        return {"type": "roughconductor", "distribution": "ggx", "alpha": float(self.alpha), "material": "none",
                "specular_reflectance": {"type": "uniform", "value": float(self.specular_reflectance)}}

    def to_dict(self) -> dict:
        """The ground truth's description: the type and the keys it uses."""
        d = {"type": self.type, **{k: getattr(self, k) for k in _USES[self.type] if k != "texture"}}
        if self.texture:  # only when set: a plain material's description (and a spec's identity) stays;
            # the file's name and content, not its folder: a moved spec keeps its identity
            d.update(texture=Path(self.texture).name, texture_sha256=self.texture_sha256)
        if self.label:
            d["label"] = self.label
        return d

    def merged(self, overrides: dict, where: str) -> "Material":
        """This material with ``overrides`` (a spec's ``material = {...}``) applied, checked."""
        v = parse_table(overrides, MATERIAL_KEYS, where, defaults=False)
        new = replace(self, **v)
        wrong = [k for k in overrides if k not in ("type", "label") and k not in _USES[new.type]]
        if wrong:
            raise InputError(f"{where}: {', '.join(sorted(wrong))} does not apply to type = {new.type!r} "
                             f"(it uses {', '.join(_USES[new.type])}); remove it or change the type")
        return new


_M = Material()
MATERIAL_KEYS = [
    Key("type", "str", _M.type, "", "diffuse: Lambertian; roughplastic: diffuse base under a rough dielectric "
        "coat (specular sheen); roughconductor: rough achromatic metal", choices=MATERIAL_TYPES),
    Key("albedo", "float", _M.albedo, "", "Lambertian albedo (diffuse; roughplastic: of the base under the coat)",
        0.0, 1.0),
    Key("alpha", "float", _M.alpha, "", "GGX roughness (roughplastic, roughconductor)", 1e-3, 1.0),
    Key("eta", "float", _M.eta, "", "interior index of refraction of the coat (roughplastic)", 1.0, 3.0),
    Key("specular_reflectance", "float", _M.specular_reflectance, "", "the metal's reflectance (roughconductor: a "
        "perfect conductor scaled by it)", 0.0, 1.0),
    Key("label", "str", "", "", "free text name recorded in the ground truth (e.g. black_matte)"),
    Key("texture", "str", "", "", "diffuse, on any shape or the board: an image file (PNG, TIFF, ...; "
        "relative to the spec) printed over the shape's bounding box in its own frame (rectangle: itself; "
        "circle, ring: the outer diameter's square; ellipse: its axes; polygon: its vertices' extent; grid: "
        "the outer element edges, each element showing its part; the board: the whole board), stretched to "
        "it, its top-left pixel at the box's top-left corner (turned with the shape), seen only inside the "
        "shape (not in a ring's hole); reflectance = albedo x the pixel's gray level / full scale (linear, "
        f"no sRGB decoding); at most {MAX_TEXTURE_PX} px a side; the truth records its corners on the board "
        "and in the image"),
]
assert {f.name for f in fields(Material)} - {"texture_sha256"} == {k.name for k in MATERIAL_KEYS}

BOARD_MATERIAL = Material("diffuse", albedo=0.8, label="white_matte")


def material_from_dict(d: dict, where: str, base: Material = _M) -> Material:
    """A ``Material`` from a spec table, over ``base`` (the keys not given keep ``base``'s values)."""
    return base.merged(d, where)


@functools.lru_cache(maxsize=16)
def texture_levels(path: str, sha256: str = "") -> "np.ndarray":
    """(H, W) float32 reflectance factors in [0, 1] of a texture image (gray level / full scale; a float
    image as it is, checked to lie in [0, 1]).  ``sha256`` keys the cache (a changed file is read again)."""
    import numpy as np

    from edgetruth.image_io import read_gray

    img = read_gray(path)
    if img.ndim != 2:
        raise InputError(f"{path}: texture has shape {img.shape}; give a gray or colour image")
    h, w = img.shape
    if min(h, w) < 1 or max(h, w) > MAX_TEXTURE_PX:
        raise InputError(f"{path}: texture is {w} x {h} px; give one of at most {MAX_TEXTURE_PX} px a side")
    if np.issubdtype(img.dtype, np.integer):
        return (img.astype(np.float64) / np.iinfo(img.dtype).max).astype(np.float32)
    img = np.asarray(img, np.float64)
    if not np.all(np.isfinite(img)) or img.min() < 0 or img.max() > 1:
        raise InputError(f"{path}: a float texture must lie in [0, 1] (it holds {np.nanmin(img):g} .. "
                         f"{np.nanmax(img):g}); scale it")
    return img.astype(np.float32)


def with_texture_file(m: Material, base_dir, where: str) -> Material:
    """``m`` with its texture path made absolute (relative to ``base_dir``: the spec's folder), the file
    read and checked (one-line errors) and its SHA-256 recorded; ``m`` itself without a texture."""
    if not m.texture:
        return m
    from edgetruth.fileio import sha256_file

    p = Path(m.texture)
    if not p.is_absolute():
        p = Path(base_dir or ".") / p
    if not p.is_file():
        raise InputError(f"{where}: texture = {m.texture!r}: no such file ({p}); give an image path relative "
                         "to the spec")
    p = p.resolve()
    sha = sha256_file(p)
    try:
        texture_levels(str(p), sha)
    except InputError as e:
        raise InputError(f"{where}: texture: {e}") from None
    return replace(m, texture=str(p), texture_sha256=sha)


_POLAR_REGISTERED: set = set()


def polar_print_plugin() -> str:
    """The name of a Mitsuba texture (a Python plugin, registered once per variant) that prints an image on a
    disk: Mitsuba's disk gives polar uv = (r, angle / 2 pi), which this turns into the disk's local point
    (x, y) = r (cos, sin)(2 pi v) and then into the image's uv by the affine map of ``Material.to_bsdf``.
    (Python plugins are traced into the kernel on the JIT variants: no per-sample cost there.)"""
    import drjit as dr
    import mitsuba as mi

    name = "edgetruth_polar_print"
    if mi.variant() in _POLAR_REGISTERED:
        return name

    class PolarPrint(mi.Texture):
        def __init__(self, props):
            mi.Texture.__init__(self, props)
            self.inner = props["texture"]
            self.m = [float(props[k]) for k in ("u0", "ux", "uy", "v0", "vx", "vy")]

        def _si(self, si):
            out = mi.SurfaceInteraction3f(si)
            ang = dr.two_pi * si.uv.y
            x, y = si.uv.x * dr.cos(ang), si.uv.x * dr.sin(ang)
            u0, ux, uy, v0, vx, vy = self.m
            out.uv = mi.Point2f(u0 + ux * x + uy * y, v0 + vx * x + vy * y)
            return out

        def eval(self, si, active=True):
            return self.inner.eval(self._si(si), active)

        def eval_1(self, si, active=True):
            return self.inner.eval_1(self._si(si), active)

        def eval_3(self, si, active=True):
            return self.inner.eval_3(self._si(si), active)

        def mean(self):
            return self.inner.mean()

        def max(self):
            return self.inner.max()

        def is_spatially_varying(self):
            return True

        def traverse(self, callback):
            pass

        def to_string(self):
            return "PolarPrint"

    mi.register_texture(name, lambda props: PolarPrint(props))
    _POLAR_REGISTERED.add(mi.variant())
    return name
