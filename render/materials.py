"""Materials of the targets and the board: diffuse albedo, rough plastic, rough conductor.

A ``Material`` is pure data (frozen, hashable: it keys the loaded scenes), read from a spec's
``material = {...}`` tables, written into the ground truth and turned into a Mitsuba BSDF dict.
Every material is achromatic (R = G = B), as the renderer keeps one channel.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace

from edgetruth.errors import InputError
from edgetruth.render.schema import Key, parse_table

MATERIAL_TYPES = ("diffuse", "roughplastic", "roughconductor")
#: the keys each material type uses (the others are refused when given)
_USES = {"diffuse": ("albedo",), "roughplastic": ("albedo", "alpha", "eta"),
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

    def to_bsdf(self) -> dict:
        """The Mitsuba BSDF dict (the same dicts the fixed T1-T4 scene used)."""
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
        d = {"type": self.type, **{k: getattr(self, k) for k in _USES[self.type]}}
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
]
assert {f.name for f in fields(Material)} == {k.name for k in MATERIAL_KEYS}

BOARD_MATERIAL = Material("diffuse", albedo=0.8, label="white_matte")


def material_from_dict(d: dict, where: str, base: Material = _M) -> Material:
    """A ``Material`` from a spec table, over ``base`` (the keys not given keep ``base``'s values)."""
    return base.merged(d, where)
