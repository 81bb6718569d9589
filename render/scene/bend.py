"""A board that is not flat: a printed sheet's curl, as a height polynomial of its board coordinates.

The height (metres, along the board's +z: into the board, away from a camera that faces it) is
z = s · Σ c_k m_k(x/s, y/s), where (x, y) are board-frame coordinates (centred on the printed squares), s
is half the larger side of the squares' bounding box (``scale_m``: a coefficient c_k is the monomial's
height at the squares' edge) and the monomials m_k are ``height_terms``': x², xy, y² (3 coefficients: a sheet
curled into a cylinder, a dome or a saddle), then x³, x²y, xy², y³ (7).  Constant and linear heights are a
pose, so there are none.  ``edgetruth.evaluate.board_bend`` fits the same terms to calibration corners.

Rendered, the plate and the squares are triangle meshes fine enough that no chord leaves the surface by more
than ``mesh_sag_m`` (checked: it must stay below a quarter of the squares' 10 µm stand-off, or the plate could
show through them).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edgetruth.errors import InputError
from edgetruth.render.scene.shapes import TARGET_STANDOFF_M

#: coefficients given -> the degrees of the monomials
DEGREES = {3: (2,), 7: (2, 3)}
#: the mesh's largest cell side (m): its chords stay within ~0.2 µm of a 1 mm curl over 100 mm
MESH_STEP_M = 0.002
#: most cells along a side of the plate mesh (a large board gets larger cells; ``mesh_sag_m`` says what it costs)
MAX_CELLS = 400
#: the largest chord sag allowed: a quarter of the squares' stand-off from the plate
MAX_SAG_M = TARGET_STANDOFF_M / 4


def height_terms(xy: np.ndarray, degrees=(2,)) -> np.ndarray:
    """(n, k) the monomials x^i y^j of dimensionless board coordinates (n, 2), i + j in ``degrees``, x's
    power falling: degree 2 gives x², xy, y²; degree 3 x³, x²y, xy², y³."""
    x, y = np.asarray(xy, float).T
    return np.stack([x ** (d - j) * y ** j for d in degrees for j in range(d + 1)], axis=1)


def term_names(degrees=(2,)) -> list[str]:
    def mono(i, j):
        part = lambda v, p: "" if p == 0 else (v if p == 1 else f"{v}^{p}")  # noqa: E731
        return part("x", i) + part("y", j)

    return [mono(d - j, j) for d in degrees for j in range(d + 1)]


@dataclass(frozen=True)
class BoardBend:
    """The height of a curled board (module docstring): ``coefficients_mm`` (3 or 7) over ``scale_m``."""

    coefficients_mm: tuple
    scale_m: float

    @classmethod
    def of(cls, coefficients_mm, squares_local: np.ndarray) -> "BoardBend":
        """The bend of coefficients (mm) over the board whose printed squares' corners are ``squares_local``
        (..., 2 or 3; board frame)."""
        c = tuple(float(v) for v in coefficients_mm)
        if len(c) not in DEGREES:
            raise InputError(f"board_bend_mm = {list(c)}: give 3 (x², xy, y²) or 7 (and x³, x²y, xy², y³) "
                             "coefficients in mm")
        xy = np.asarray(squares_local, float).reshape(-1, np.shape(squares_local)[-1])[:, :2]
        return cls(c, float(np.abs(xy).max()))

    @property
    def degrees(self) -> tuple:
        return DEGREES[len(self.coefficients_mm)]

    def height_m(self, xy: np.ndarray) -> np.ndarray:
        """(n,) heights (m, along board +z) at board points (n, >= 2)."""
        p = np.asarray(xy, float)[:, :2] / self.scale_m
        return height_terms(p, self.degrees) @ (np.asarray(self.coefficients_mm) * 1e-3)

    def lift(self, points_local: np.ndarray) -> np.ndarray:
        """Board points (..., 3) moved along z by the height at their (x, y)."""
        p = np.array(points_local, dtype=np.float64)
        flat = p.reshape(-1, 3)
        flat[:, 2] += self.height_m(flat)
        return flat.reshape(p.shape)

    def sag_m(self, verts_xy: np.ndarray, faces: np.ndarray) -> float:
        """Largest distance (m, along z) between the mesh's triangles (``faces`` into ``verts_xy``) and the
        surface, at their edges' midpoints and centroids (on these right-triangle cells a quadratic's largest
        gap is at an edge's middle; a cubic's close to it at this cell size)."""
        v = np.asarray(verts_xy, float)[:, :2]
        h = self.height_m(v)
        tri = np.asarray(faces)
        worst = 0.0
        for a, b in ((0, 1), (1, 2), (2, 0)):
            mid = 0.5 * (v[tri[:, a]] + v[tri[:, b]])
            worst = max(worst, float(np.abs(self.height_m(mid) - 0.5 * (h[tri[:, a]] + h[tri[:, b]])).max()))
        cen = v[tri].mean(axis=1)
        return max(worst, float(np.abs(self.height_m(cen) - h[tri].mean(axis=1)).max()))

    def to_dict(self) -> dict:
        return {"coefficients_mm": list(self.coefficients_mm), "terms": term_names(self.degrees),
                "scale_m": self.scale_m,
                "meaning": "height along board +z (into the board, away from the camera) z = s * sum c_k "
                           "m_k(x / s, y / s) in the board frame (centred on the printed squares), s = scale_m "
                           "(half the larger side of the squares' bounding box); c_k = coefficients_mm / 1000"}


def _cells(length_m: float) -> int:
    return int(min(MAX_CELLS, max(1, math.ceil(length_m / MESH_STEP_M))))


def grid_mesh(quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each quad (n, 4, 3: top-left, top-right, bottom-right, bottom-left, planar, wound as
    ``CheckerRig``'s) cut bilinearly into cells of at most ``MESH_STEP_M`` -> (vertices (m, 3), faces (k, 3)),
    every cell wound as the quad (its straight sides stay straight: the cut is exact on a planar quad)."""
    verts, faces, base = [], [], 0
    for q in np.asarray(quads, float):
        nu = _cells(max(np.linalg.norm(q[1] - q[0]), np.linalg.norm(q[2] - q[3])))
        nv = _cells(max(np.linalg.norm(q[3] - q[0]), np.linalg.norm(q[2] - q[1])))
        u = np.linspace(0.0, 1.0, nu + 1)[None, :, None]
        w = np.linspace(0.0, 1.0, nv + 1)[:, None, None]
        top = q[0] + (q[1] - q[0]) * u
        bottom = q[3] + (q[2] - q[3]) * u
        g = (top + (bottom - top) * w).reshape(-1, 3)  # row-major: v rows of nu + 1
        i, j = np.meshgrid(np.arange(nu), np.arange(nv))
        tl = (j * (nu + 1) + i).ravel() + base
        tr, bl = tl + 1, tl + nu + 1
        br = bl + 1
        faces.append(np.concatenate([np.stack([tl, br, tr], 1), np.stack([tl, bl, br], 1)]))
        verts.append(g)
        base += len(g)
    return np.concatenate(verts), np.concatenate(faces)


def check_sag(bend: BoardBend, verts: np.ndarray, faces: np.ndarray, where: str) -> float:
    sag = bend.sag_m(verts, faces)
    if sag > MAX_SAG_M:
        raise InputError(f"{where}: board_bend_mm = {list(bend.coefficients_mm)}: the board's mesh leaves its "
                         f"surface by {sag * 1e6:.1f} µm (most {MAX_SAG_M * 1e6:g}); give a gentler bend")
    return sag
