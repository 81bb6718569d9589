"""The shape catalogue's edges: each shape's rendered edge lies on its exact distorted outline.

An in-focus pinhole camera with lens distortion and no PSF, box filter, matte shapes under a point light
(flat regions noiseless: only the pixel sampling at the edges is Monte-Carlo).  A pixel's value is then
A + (B - A) x (the part of it on the board), so summing the bright part of a pixel column (row) across an
edge gives the edge's mean height over that column (row) exactly -- a measurement that knows nothing of
the outline.  Per side (polygon) or quarter arc (conic) a line fit to (measured - exact) must stay within
0.01 px over the piece.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from edgetruth.render.optics.camera import Camera
from edgetruth.render.scene.lights import Light
from edgetruth.render.scene.materials import Material
from edgetruth.render.scene.outline import OutlineCurve
from edgetruth.render.scene.pose import Pose
from edgetruth.render.scene.shapes import Shape
from edgetruth.render.scene.target_scene import TargetScene

TOL_PX = 0.01
HALF_WINDOW_PX = 5
PAD_PX = 5  # flat pixels on each side of the window: the two levels
CAMERA = Camera(width_px=200, height_px=150, pitch_um=24.0, focal_length_mm=8.0, f_number=0.0,
                focus_distance_m=0.6, distortion=(-0.08, 0.03, 2e-4, -1e-4, 0.0), diffraction_wavelength_nm=0.0,
                natural_vignetting=False)
POSE = Pose(0.6, 0.0, 0.0, 4.0, -3.0, 0.0)  # slightly tilted: perspective as well as distortion
BLACK = Material("diffuse", albedo=0.04)
SHAPES = {
    "rectangle": Shape("rectangle", offset_m=(-0.06, -0.04), rotation_deg=20.0, width_m=0.06, height_m=0.035,
                       material=BLACK),
    "circle": Shape("circle", offset_m=(0.05, -0.045), diameter_m=0.05, material=BLACK),
    "ellipse": Shape("ellipse", offset_m=(-0.065, 0.045), rotation_deg=30.0, axes_m=(0.07, 0.04), material=BLACK),
    "ring": Shape("ring", offset_m=(0.09, 0.06), outer_diameter_m=0.1, inner_diameter_m=0.05, material=BLACK),
    "polygon": Shape("polygon", offset_m=(0.0, 0.0), rotation_deg=10.0,
                     vertices_m=((-0.02, -0.02), (0.025, -0.015), (0.0, 0.0), (0.02, 0.02), (-0.015, 0.02)),
                     material=BLACK),
}
SCENE = TargetScene("edges", tuple(SHAPES.values()),
                    lights=(Light("point", position_m=(0.0, -0.1, -0.05)),))


@pytest.fixture(scope="module")
def rendered(fast_variant):
    import mitsuba as mi

    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    mi.set_variant(fast_variant)
    rig = TargetRig(CAMERA, RenderSettings(spp=1024, sampler="multijitter"))
    rig.set_state(SCENE, POSE, 1.0)
    return rig.render(7).astype(np.float64)


def _curves():
    out = []
    for k, s in enumerate(SCENE.shapes):
        for o in s.outlines():
            out.append((k, o, OutlineCurve.of(CAMERA, POSE, o, (k + 1) * 10e-6)))
    return out


def _strip_mean(curve, t_dense, pts, i, axis):
    """Exact mean of the curve's other coordinate over the strip [i - 1/2, i + 1/2] of ``axis``."""
    a = pts[:, axis]
    sel = (a >= i - 0.75) & (a <= i + 0.75)
    if sel.sum() < 4:
        return None
    order = np.argsort(a[sel])
    xs = np.linspace(i - 0.5, i + 0.5, 201)
    return float(np.mean(np.interp(xs, a[sel][order], pts[sel, 1 - axis][order])))


def measure_piece(img, curve, t0, t1, others):
    """(position along the piece in [-1, 1], measured - exact) per usable pixel strip of one side or arc."""
    t_dense = np.linspace(t0, t1, 4000)
    pts = curve.points(t_dense)
    d = np.gradient(pts, axis=0)
    nrm = np.column_stack([-d[:, 1], d[:, 0]]) / np.linalg.norm(d, axis=1)[:, None]
    axis = 0 if np.median(np.abs(nrm[:, 1])) > np.median(np.abs(nrm[:, 0])) else 1  # strips along x: columns
    lo, hi = pts[:, axis].min(), pts[:, axis].max()
    res, pos = [], []
    h, w = img.shape
    for i in range(int(math.ceil(lo + 1)), int(math.floor(hi - 1)) + 1):
        near = np.abs(pts[:, axis] - i) <= 0.5
        if not near.any() or np.min(np.abs(nrm[near, 1 - axis])) < 0.8:
            continue  # steep here: the other strip direction measures it
        e = float(np.mean(pts[near, 1 - axis]))
        r0, r1 = int(round(e)) - HALF_WINDOW_PX, int(round(e)) + HALF_WINDOW_PX
        if r0 - PAD_PX < 0 or r1 + PAD_PX >= (h if axis == 0 else w) or i < 0 or i >= (w if axis == 0 else h):
            continue
        box_lo, box_hi = np.array([i - 1.0, r0 - PAD_PX - 0.5]), np.array([i + 1.0, r1 + PAD_PX + 0.5])
        if axis == 1:
            box_lo, box_hi = box_lo[::-1], box_hi[::-1]
        if any(np.any(np.all((o >= box_lo) & (o <= box_hi), axis=1)) for o in others):
            continue  # another edge in the window
        line = img[r0 - PAD_PX:r1 + PAD_PX + 1, i] if axis == 0 else img[i, r0 - PAD_PX:r1 + PAD_PX + 1]
        j = np.arange(r0 - PAD_PX, r1 + PAD_PX + 1, dtype=float)
        # each side's level as a line through its PAD_PX outer pixels: the light's gradient across the
        # window (~1e-3 per px) would otherwise move the sum by ~0.02 px
        head, tail = np.polyfit(j[:PAD_PX], line[:PAD_PX], 1), np.polyfit(j[-PAD_PX:], line[-PAD_PX:], 1)
        jj = j[PAD_PX:-PAD_PX]
        lh, lt = np.polyval(head, jj), np.polyval(tail, jj)
        bright_tail = lt.mean() > lh.mean()
        dark, bright = (lh, lt) if bright_tail else (lt, lh)
        c = (line[PAD_PX:-PAD_PX] - dark) / (bright - dark)
        measured = (r1 + 0.5) - c.sum() if bright_tail else (r0 - 0.5) + c.sum()
        exact = _strip_mean(curve, t_dense, pts, i, axis)
        if exact is None:
            continue
        res.append(measured - exact)
        pos.append(i)
    pos = np.asarray(pos, float)
    if len(pos) < 2:
        return pos, np.asarray(res)
    return 2 * (pos - pos.min()) / max(np.ptp(pos), 1e-9) - 1, np.asarray(res)


def _pieces(o):
    if o.kind == "polygon":
        n = len(o.vertices)
        return [(j / n + 1e-6, (j + 1) / n - 1e-6) for j in range(n)]
    return [(q / 8 + 1e-6, (q + 1) / 8 - 1e-6) for q in range(8)]  # octants: one strip direction each


@pytest.mark.parametrize("name", list(SHAPES))
def test_rendered_edge_on_exact_outline(rendered, name):
    k = list(SHAPES).index(name)
    curves = _curves()
    fitted = []
    for kk, o, curve in curves:
        if kk != k:
            continue
        for t0, t1 in _pieces(o):
            others = [c.points(np.linspace(0, 1, 4000)) for kk2, o2, c in curves if c is not curve]
            # the rest of the same outline (neighbouring sides, the far side of a conic)
            gap = 1e-5 if o.kind == "polygon" else 0.1  # a conic's own continuation is the same edge
            rest = curve.points(np.linspace(t1 + gap, t0 + 1 - gap, 4000))
            pos, r = measure_piece(rendered, curve, t0, t1, others + [rest])
            if len(r) < 4:
                continue
            b, a = np.polyfit(pos, r, 1)
            fitted.append((o.name, t0, len(r), a, b, max(abs(a - b), abs(a + b)), float(np.std(r))))
    assert len(fitted) >= (3 if SHAPES[name].type in ("rectangle", "polygon") else 4), fitted
    worst = max(f[5] for f in fitted)
    assert worst <= TOL_PX, [tuple(round(v, 4) if isinstance(v, float) else v for v in f) for f in fitted]


# --- occlusion: a lighter disk on top of a dark rectangle's corner ------------------------------------
UNDER = Shape("rectangle", offset_m=(-0.02, 0.0), rotation_deg=10.0, width_m=0.1, height_m=0.07, material=BLACK)
OVER = Shape("circle", offset_m=(0.03, 0.03), diameter_m=0.07, material=Material("diffuse", albedo=0.4))
OCCLUDED = TargetScene("occluded", (UNDER, OVER), lights=SCENE.lights)


@pytest.fixture(scope="module")
def rendered_occluded(fast_variant):
    from edgetruth.render.scene.mitsuba_scene import RenderSettings, TargetRig

    rig = TargetRig(CAMERA, RenderSettings(spp=1024, sampler="multijitter"))
    rig.set_state(OCCLUDED, POSE, 1.0)
    return rig.render(8).astype(np.float64)


def test_occluded_outline_is_the_visible_edge(rendered, rendered_occluded):
    """The visible outline (the rectangle's sides outside the disk, the whole disk) is where the image's
    edges are, within 0.01 px (the disk's edge over the rectangle is a dark-to-gray edge, over the board a
    gray-to-white one); along the hidden part of the rectangle's outline the image has no edge."""
    from edgetruth.render.scene.ground_truth import shape_outline_truth

    img = rendered_occluded
    c_under = OutlineCurve.of(CAMERA, POSE, UNDER.outlines()[0], 10e-6)
    c_over = OutlineCurve.of(CAMERA, POSE, OVER.outlines()[0], 20e-6)
    vis = shape_outline_truth(CAMERA, POSE, OCCLUDED, 0)[0]["visible_intervals"]
    assert len(vis) == 1  # the disk hides one run of the outline, across the top-right corner
    v0, v1 = vis[0]
    visible_under = c_under.points(np.linspace(v0, v1, 4000))
    over_pts = c_over.points(np.linspace(0, 1, 4000))
    fitted = []
    for j in range(4):  # each side's visible part (the visible run may wrap past t = 1)
        lo, hi = j / 4, (j + 1) / 4
        for t0, t1 in [(max(lo, s), min(hi, e)) for s, e in ((v0, v1), (v0 - 1, v1 - 1)) if min(hi, e) > max(lo, s)]:
            t_rest = np.linspace(t1 + 1e-5, t0 + 1 - 1e-5, 4000)
            rest = c_under.points(t_rest)[~OVER.covers(UNDER.outlines()[0].local_xy(t_rest))]  # visible only
            pos, r = measure_piece(img, c_under, t0 + 1e-6, t1 - 1e-6, [over_pts, rest])
            if len(r) >= 4:
                fitted.append(("under", j, len(r), max(abs(np.polyval(np.polyfit(pos, r, 1), [-1, 1])))))
    for t0, t1 in _pieces(OVER.outlines()[0]):
        rest = c_over.points(np.linspace(t1 + 0.1, t0 + 0.9, 4000))
        pos, r = measure_piece(img, c_over, t0, t1, [visible_under, rest])
        if len(r) >= 4:
            fitted.append(("over", t0, len(r), max(abs(np.polyval(np.polyfit(pos, r, 1), [-1, 1])))))
    assert sum(f[0] == "under" for f in fitted) >= 3 and sum(f[0] == "over" for f in fitted) >= 6, fitted
    assert max(f[3] for f in fitted) <= TOL_PX, fitted
    # the hidden run: inside the disk, 3 px either side of the rectangle's outline read the disk alone
    t_hidden = np.linspace(v1 - 1 + 0.01 * (1 + v0 - v1), v0 - 0.01 * (1 + v0 - v1), 40) % 1.0
    p = c_under.points(t_hidden)
    d = c_under.points(t_hidden + 1e-6) - p
    n = np.column_stack([-d[:, 1], d[:, 0]]) / np.linalg.norm(d, axis=1)[:, None]
    inside_over = c_over.signed_distance(p[:, 0], p[:, 1]) < -5.0
    assert inside_over.sum() >= 5
    pin = np.rint(p[inside_over] - 3 * n[inside_over]).astype(int)
    pout = np.rint(p[inside_over] + 3 * n[inside_over]).astype(int)
    inner, outer = img[pin[:, 1], pin[:, 0]], img[pout[:, 1], pout[:, 0]]
    # a real edge there (dark 0.04 under the disk's 0.4) would differ by ~90 %; the light's gradient over
    # 6 px is ~1.5 %
    assert np.max(np.abs(inner - outer) / outer) < 0.05
