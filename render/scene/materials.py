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
    #: diffuse only: an image printed on the surface (a rectangle shape or the board), its gray level times
    #: ``albedo``; the absolute path and its SHA-256 once the spec is loaded (``with_texture_file``)
    texture: str = ""
    texture_sha256: str = ""

    def to_bsdf(self) -> dict:
        """The Mitsuba BSDF dict (the same dicts the fixed T1-T4 scene used)."""
        if self.type == "diffuse" and self.texture:
            import mitsuba as mi

            # nearest texel: the print's texels are squares with sharp edges (the ground truth's placement)
            data = (self.albedo * texture_levels(self.texture, self.texture_sha256))[::-1, :, None]
            return {"type": "diffuse", "reflectance": {"type": "bitmap", "data": mi.TensorXf(data.copy()),
                                                       "raw": True, "filter_type": "nearest", "wrap_mode": "clamp"}}
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
    Key("texture", "str", "", "", "diffuse, on a rectangle shape or the board: an image file (PNG, TIFF, ...; "
        "relative to the spec) printed over the whole surface, its top-left pixel at the surface's top-left "
        "corner; reflectance = albedo x the pixel's gray level / full scale (linear, no sRGB decoding); "
        f"at most {MAX_TEXTURE_PX} px a side; the truth records its corners on the board and in the image"),
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
