"""Per-point truth on renders: every method's points on the raw image scored against the exact outline.

The ranging chain works on the undistorted (resampled) image, where the truth is only as good as
the calibration.  Edge-level errors are measured on the *raw* image instead: the target's Canny
boundary candidates there (``edgetruth.evaluate.target``) are refined by every method and
each point's error is its signed distance to the exact distorted outline of the ground truth
(``edgetruth.render.edge_truth.OutlineEdge``: the JSON's dense polyline, chords within 1e-3 px of
the curve; > 0 on the bright board, as the synthetic study's errors are > 0 on the bright side).

Which candidates are scored (one rule for every method, as ``edgetruth.evaluate.matching``):

- *on the edge*: the candidate pixel centre lies within ``MATCH_RADIUS_PX`` (1.5 px) of the outline;
- *not at a corner*: squares only -- the candidate lies farther than ``CORNER_EXCLUSION_PX`` (4 px)
  from every true (distorted) corner, where the profile across one side also crosses the other
  and no edge model of the study applies.

An image with several outlines (a scene: shapes that cover one another, a ring's two edges, clutter) has no one
target to find: its candidates are Canny's along every visible edge (``scene_candidates``), each scored against
the nearest visible edge (``SceneOutline``); its per-point bounds and optical offsets, which follow one outline's
geometry and the shading either side of it, are NaN there.

A method that declines or fails a candidate answers with the candidate pixel (``converged`` False).
The tables keep the figures apart (``edgetruth.evaluate.stats``): coverage, accuracy on the points
the method refines, on the common subset every compared method refines, and on all candidates with
the declines scored at the pixel centre.

The optical edge: where the ground truth JSON carries ``outline.optical_edge``
(``edgetruth.render.optics.optical_edge``: the displacement of the image edge from the geometric outline
that the camera model predicts, per polyline point), each scored candidate also records the offset
at its place (``optical_offset``: the centroid; ``optical_offset_50``: the 50 % level), so that the
tables give a method's bias against the optical edge, e = d_geometric − offset, and the optics'
own displacement apart.  Older JSONs: NaN.

The per-point bound (``bounds``, per method and point): the exact Cramér–Rao bound of
``edgetruth.evaluate.points.bound`` -- the camera's PSF at the point's field height, the outline's
orientation and curvature, the shading on both sides, the sensor's signal-dependent noise, over the
method's declared footprint, the nuisances (normal, levels, PSF scale) estimated.  The old figure
stays as a named reference only (``point_bound_px``, the image record's ``bound_row_px``): the
bound of an axis-aligned 11-pixel row across a pixel-integrated Gaussian edge
(``edgetruth.evaluate.crb.position_std_bound``, A, B, μ, σ unknown) whose σ is the Gaussian
equivalent of the lens PSF and defocus disk at the target (Airy core 0.42 λN, aberration σ(h),
disk radius R as R/2), contrast and noise at the edge's mid level; not a floor for oblique sides
and 2-D methods.
"""
from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass, field

import numpy as np

from edgetruth import locate
from edgetruth.errors import InputError
from edgetruth.evaluate.matching import MATCH_RADIUS_PX
from edgetruth.evaluate.method_order import resolve
from edgetruth.evaluate.points.bound import esf_for_points, point_bounds, sensor_variance
from edgetruth.evaluate.target import TargetCandidates, is_scene, target_candidates
from edgetruth.fileio import atomic_write_bytes
from edgetruth.render.optics.optical_edge import nearest_offsets
from edgetruth.render.scene.ground_truth import image_outline


CORNER_EXCLUSION_PX = 4.0
BOUND_WINDOW_PX = 11
_AIRY_GAUSS = 0.42  # σ of the Gaussian that best fits the Airy core, in units of λN


@dataclass
class PointScores:
    """One image's per-point scores: its scored candidates and every method's signed errors on them.

    Attributes
    ----------
    n_candidates : int
        Boundary candidates before the on-edge and corner rules.
    bound_px : float
        The image's 11-pixel-row reference figure (a reference column, not a floor on oblique edges).
    candidate_distance : numpy.ndarray
        (N,) signed distance of each scored candidate's pixel centre to the exact outline, px.
    errors : dict of str to numpy.ndarray
        Method label -> (N,) signed error of its point along the true normal, px (> 0 on the bright board).
    converged : dict of str to numpy.ndarray
        Method label -> (N,) bool.
    windows : dict of str to numpy.ndarray
        Dynamic methods' label -> (N,) window size chosen (samples).
    optical_offset, optical_offset_50 : numpy.ndarray or None
        (N,) the optical edge's centroid and 50 % level offsets at each candidate, px.
    bounds : dict of str to numpy.ndarray
        Method label -> (N,) exact per-point Cramér-Rao bound over its footprint under the camera's PSF, px.
    points : dict
        Transient: label -> (x, y, nx, ny) of the refined points (emptied before results leave a worker).
    """

    n_candidates: int  # boundary candidates before the on-edge and corner rules
    bound_px: float  # the 11-pixel-row reference figure of the image (module docstring), not a floor
    candidate_distance: np.ndarray  # (N,) truth at the candidate pixel centres
    errors: dict = field(default_factory=dict)  # label -> (N,) signed error, px
    converged: dict = field(default_factory=dict)  # label -> (N,) bool
    windows: dict = field(default_factory=dict)  # dynamic labels -> (N,) window size (samples)
    optical_offset: np.ndarray | None = None  # (N,) optical edge's centroid offset at the candidate (px)
    optical_offset_50: np.ndarray | None = None  # (N,) its 50 % level
    bounds: dict = field(default_factory=dict)  # label -> (N,) exact per-point bound over its footprint (px)
    # label -> (x, y, nx, ny) of the refined points in image coordinates; transient: the ranging reads them
    # (its raw-image pose) and empties the dict before the result leaves the worker; never stored
    points: dict = field(default_factory=dict)


def candidate_optical_offsets(gt: dict, truth, x, y) -> tuple[np.ndarray, np.ndarray]:
    """(centroid, 50 % level) offsets of the optical edge at image points, from the JSON's
    ``outline.optical_edge`` (NaN where the JSON has none)."""
    oe = gt.get("outline", {}).get("optical_edge")
    x, y = np.asarray(x, float), np.asarray(y, float)
    if not oe or is_scene(truth):  # the JSON's optical edge is shape 0's outline
        return np.full(x.shape, np.nan), np.full(x.shape, np.nan)
    return (nearest_offsets(truth.polyline_px, oe["offset_px"], x, y),
            nearest_offsets(truth.polyline_px, oe.get("offset_50_px", oe["offset_px"]), x, y))


def scored_subset(truth, cand, offset) -> tuple[np.ndarray, np.ndarray]:
    """(keep mask over ``cand``, signed truth distance of the kept candidates) by the module's rule."""
    x0, y0 = offset
    cx, cy = cand.x + x0, cand.y + y0
    d = truth.signed_distance(cx, cy)
    keep = np.abs(d) <= MATCH_RADIUS_PX
    keep &= truth.corner_distance(cx, cy) > CORNER_EXCLUSION_PX
    return keep, d[keep]


def scene_candidates(image: np.ndarray, truth, margin_px: int = 12, boundary_tol_px: float = 2.0,
                     sigma_px: float = 1.0):
    """``TargetCandidates`` of an image with several outlines: no one target to find, so Canny runs on the crop
    around every visible edge (+ ``margin_px``) and keeps the candidates within ``boundary_tol_px`` of one, as
    ``target_candidates`` keeps those on its target's boundary (``region`` None)."""
    img = np.asarray(image, np.float64)
    seg = truth.visible_points_px()
    if not len(seg):
        raise InputError("scene: no visible edge in the image")
    h, w = img.shape[:2]
    x0, y0 = (max(int(v), 0) for v in np.floor(seg.min(axis=0)) - margin_px)
    x1, y1 = (min(int(np.ceil(v)) + margin_px + 1, n) for v, n in zip(seg.max(axis=0), (w, h)))
    if x1 - x0 < 3 or y1 - y0 < 3:
        raise InputError("scene: the visible edges lie outside the image")
    crop = np.ascontiguousarray(img[y0:y1, x0:x1])
    cand = locate.candidates(crop, sigma_px=sigma_px)
    keep = np.abs(truth.signed_distance(cand.x + x0, cand.y + y0)) <= boundary_tol_px
    return TargetCandidates(None, crop, (x0, y0), cand, cand.subset(keep), keep)


def scored_candidates(image: np.ndarray, truth):
    """The target's Canny boundary candidates on the raw ``image`` and the subset the rule scores:
    (``TargetCandidates``, scored ``Candidates``, their signed truth distance).  One definition for
    the per-point tables and the threshold calibration on renders.  An image with several outlines
    (``is_scene``) has its candidates along every visible edge (``scene_candidates``)."""
    img = np.asarray(image, np.float64)
    tc = scene_candidates(img, truth) if is_scene(truth) else target_candidates(img)
    keep, d = scored_subset(truth, tc.candidates, tc.offset)
    return tc, tc.candidates.subset(keep), d


def gaussian_equivalent_blur_px(gt: dict) -> float:
    """σ (px) of a Gaussian standing in for PSF ⊗ defocus disk at the target (pixel excluded)."""
    cam = gt["camera"]
    psf = cam.get("optics", {}).get("psf", {})
    pitch_um = float(cam["pitch_um"])
    h = float(gt.get("optics_at_target", {}).get("field_height", 0.0))
    s_ab = float(psf.get("aberration_sigma_um", 0.0)) * (1.0 + float(psf.get("aberration_sigma_growth", 0.0)) * h * h)
    lam_um = float(psf.get("diffraction_wavelength_nm", 0.0)) * 1e-3
    s_airy = _AIRY_GAUSS * lam_um * float(cam.get("f_number", 0.0))
    r_px = float(gt.get("defocus_radius_px", 0.0))
    return math.sqrt((s_ab / pitch_um) ** 2 + (s_airy / pitch_um) ** 2 + (0.5 * r_px) ** 2)


def point_bound_px(gt: dict, radiance: np.ndarray, truth) -> float:
    """The 11-pixel-row reference figure (px) of one rendered target image (module docstring): an
    approximation kept for comparison, not a floor."""
    from edgetruth.evaluate.crb import position_std_bound  # lazy: crb loads numba

    s = gt["sensor"]
    poly = truth.polyline_px
    x0, y0 = np.floor(poly.min(axis=0)).astype(int) - 16
    x1, y1 = np.ceil(poly.max(axis=0)).astype(int) + 16
    h, w = radiance.shape[:2]
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    yy, xx = np.mgrid[y0:y1, x0:x1]
    d = truth.signed_distance(xx.astype(float), yy.astype(float))
    rad = np.asarray(radiance, float)[y0:y1, x0:x1]
    rad = rad if rad.ndim == 2 else rad.mean(axis=2)
    e_per_rad = float(gt["photons_per_radiance"]) * float(s["qe"])
    bright, dark = rad[(d > 6) & (d < 12)], rad[(d < -6) & (d > -12)]
    if bright.size < 8 or dark.size < 8:
        return float("nan")
    a_e, b_e = e_per_rad * float(np.median(dark)), e_per_rad * (float(np.median(bright)) - float(np.median(dark)))
    if b_e <= 0:
        return float("nan")
    k = float(s["gain_dn_per_e"])
    sigma_e = math.sqrt(float(s["dark_noise_e"]) ** 2 + a_e + 0.5 * b_e + 1.0 / (12.0 * k * k))
    return float(position_std_bound(max(gaussian_equivalent_blur_px(gt), 0.05), sigma_e / b_e,
                                    window=BOUND_WINDOW_PX, unknowns="4p"))


def camera_options(gt: dict, x, y) -> dict:
    """patch_esf_fit's camera options at points (x, y) (full-image pixel coordinates) from the image's JSON:
    the edge-spread tables of its PSF per field-height bin (``esf``, ``bin_index``: binned as the bound) and
    the sensor's pixel variance (``variance``: the bound's EMVA model; left out -- an unweighted fit -- without
    a sensor block or on an output that is not the raw signal)."""
    if "camera" not in gt:
        return {}
    esf, bin_index = esf_for_points(gt, x, y)
    out = {"esf": esf, "bin_index": bin_index}
    sensor = gt.get("sensor")
    if sensor and str(sensor.get("output", "raw")) == "raw" and str(sensor.get("cfa", "none")) == "none":
        out["variance"] = sensor_variance(gt)
    return out


def score_image(image: np.ndarray, gt: dict, methods: list[str], options: dict | None = None,
                radiance: np.ndarray | None = None) -> PointScores:
    """Refine a rendered target image's boundary candidates with every method and score them against the truth.

    Candidates within 1.5 px of the exact distorted outline (a square's farther than 4 px from a corner;
    a scene of several outlines: along every visible edge, each against the nearest) are refined by each
    method on the raw image, and each point's error is its signed distance to the exact outline.

    Parameters
    ----------
    image : numpy.ndarray
        The raw sensor image (``Sample.image``), (H, W).
    gt : dict
        Its ground-truth JSON (``Sample.truth``).
    methods : list of str
        Method ids, with options as ``"id:key=value"`` (``edgetruth.evaluate.method_order``).
    options : dict, optional
        Options per method label, added to the studies' own.
    radiance : numpy.ndarray, optional
        The image's radiance (``Sample.radiance``); given, each point also gets its exact bound.

    Returns
    -------
    PointScores
        The scored candidates and every method's errors, px.
    """
    truth = image_outline(gt)
    tc, sub, d = scored_candidates(image, truth)
    # the bounds follow one outline's geometry and the shading either side of it: not computed for scenes
    bounded = radiance is not None and not is_scene(truth)
    bound = point_bound_px(gt, radiance, truth) if bounded else float("nan")
    out = PointScores(len(tc.candidates), bound, d.astype(np.float32))
    x0, y0 = tc.offset
    oc, o50 = candidate_optical_offsets(gt, truth, sub.x + x0, sub.y + y0)
    out.optical_offset, out.optical_offset_50 = oc.astype(np.float32), o50.astype(np.float32)
    masks, blur_known = {}, set()
    for label in methods:
        mid, kw = resolve(label, options)
        if bounded and len(sub):  # the bound's pixels: the method's declared footprint
            masks[label] = locate.METHODS[mid].footprint_masks(sub, **kw)
            if kw.get("psf_sigma_px") is not None or (mid == "patch_esf_fit" and kw.get("blur_known")):
                blur_known.add(label)  # told the PSF: its scale is known
        if len(sub):
            if mid == "patch_esf_fit":
                kw = {**camera_options(gt, sub.x + x0, sub.y + y0), **kw}
            pts = locate.refine(tc.crop, sub, mid, **kw)
            err = truth.signed_distance(pts.x + x0, pts.y + y0)
            out.points[label] = (pts.x + x0, pts.y + y0, pts.nx, pts.ny)
            conv = np.asarray(pts.converged, bool)
            if "window" in pts.extras and mid.startswith("dynamic"):
                out.windows[label] = np.asarray(pts.extras["window"], np.int8)
        else:
            err, conv = np.zeros(0), np.zeros(0, bool)
        out.errors[label] = np.asarray(err, np.float32)
        out.converged[label] = conv
    if bounded and len(sub):
        b = point_bounds(gt, radiance, truth, sub.x + x0, sub.y + y0, masks, blur_known)
        out.bounds = {m: np.asarray(v, np.float32) for m, v in b.items()}
    else:
        out.bounds = {m: np.full(len(sub), np.nan, np.float32) for m in methods}
    return out


# --- storage: one npz per evaluation -------------------------------------------------------------
POINTS_FILE = "render_points.npz"


@dataclass
class PointTable:
    """Every scored point of an evaluation, with its image's record."""

    images: list[dict]
    image: np.ndarray  # (N,) index into images
    errors: dict  # label -> (N,)
    converged: dict
    windows: dict
    optical_offset: np.ndarray | None = None  # (N,) per point, px (NaN: the JSON had no optical edge)
    optical_offset_50: np.ndarray | None = None
    bounds: dict = field(default_factory=dict)  # label -> (N,) exact per-point bound (px), NaN unknown

    def bound(self, m: str) -> np.ndarray:
        """Method ``m``'s exact per-point bound (px); NaN where unknown (older files)."""
        v = self.bounds.get(m)
        return np.full(len(self.image), np.nan) if v is None else np.asarray(v, float)

    def optical(self, which: str = "centroid") -> np.ndarray:
        """Per point: the optical edge's offset from the outline (px), NaN where unknown."""
        v = self.optical_offset if which == "centroid" else self.optical_offset_50
        return np.full(len(self.image), np.nan) if v is None else np.asarray(v, float)

    @property
    def methods(self) -> list[str]:
        return list(self.errors)

    def select(self, image_mask: np.ndarray) -> "PointTable":
        """The points of the images where ``image_mask`` (over ``images``) is True."""
        keep = np.asarray(image_mask, bool)[self.image] if len(self.image) else np.zeros(0, bool)
        return PointTable(self.images, self.image[keep], {m: v[keep] for m, v in self.errors.items()},
                          {m: v[keep] for m, v in self.converged.items()}, {m: v[keep] for m, v in self.windows.items()},
                          None if self.optical_offset is None else self.optical_offset[keep],
                          None if self.optical_offset_50 is None else self.optical_offset_50[keep],
                          {m: v[keep] for m, v in self.bounds.items()})


def read_points(path) -> PointTable:
    try:
        z = np.load(path, allow_pickle=False)
        images = json.loads(str(z["images_json"]))
        names = [k.split("/", 1)[1] for k in z.files if k.startswith("error/")]
        return PointTable(images, z["image"], {m: z[f"error/{m}"].astype(float) for m in names},
                          {m: z[f"converged/{m}"] for m in names},
                          {m: z[f"window/{m}"] for m in names if f"window/{m}" in z.files},
                          z["optical_offset"].astype(float) if "optical_offset" in z.files else None,
                          z["optical_offset_50"].astype(float) if "optical_offset_50" in z.files else None,
                          {m: z[f"bound/{m}"].astype(float) for m in names if f"bound/{m}" in z.files})
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"{path}: not a readable {POINTS_FILE} ({exc}); re-run the evaluation") from None


def write_points(path, table: "PointTable") -> None:
    """``render_points.npz``: ``image`` (per point: index into ``images_json``), ``error/<label>``
    (float32 px), ``converged/<label>``, ``window/<label>`` (dynamic methods), ``bound/<label>`` (the
    exact per-point bound over the method's footprint, px), ``optical_offset`` and ``optical_offset_50``
    (per point, the optical edge's offset, px; NaN without one), and ``images_json`` (one record per
    image: dataset, image, spec, group, slot, levels, off_base, target, interval, true_distance_m,
    bound_row_px (the 11-pixel-row reference), n_candidates, n_scored)."""
    arrays = {"image": table.image.astype(np.int32), "images_json": np.array(json.dumps(table.images))}
    for m in table.methods:
        arrays[f"error/{m}"] = table.errors[m].astype(np.float32)
        arrays[f"converged/{m}"] = table.converged[m].astype(bool)
        if m in table.windows:
            arrays[f"window/{m}"] = table.windows[m].astype(np.int8)
        if m in table.bounds:
            arrays[f"bound/{m}"] = np.asarray(table.bounds[m], np.float32)
    for key in ("optical_offset", "optical_offset_50"):
        v = getattr(table, key)
        if v is not None:
            arrays[key] = np.asarray(v, np.float32)
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def table_from_scores(images: list[dict], scores: list[PointScores], methods: list[str]) -> PointTable:
    """One ``PointTable`` from per-image records and their scores (same order)."""
    recs = [dict(r, bound_row_px=s.bound_px, n_candidates=s.n_candidates, n_scored=len(s.candidate_distance))
            for r, s in zip(images, scores)]

    def cat(get, dtype):
        return np.concatenate([np.asarray(get(s), dtype) for s in scores]) if scores else np.zeros(0, dtype)

    image = (np.concatenate([np.full(len(s.candidate_distance), k, np.int32) for k, s in enumerate(scores)])
             if scores else np.zeros(0, np.int32))
    return PointTable(recs, image, {m: cat(lambda s: s.errors[m], float) for m in methods},
                      {m: cat(lambda s: s.converged[m], bool) for m in methods},
                      {m: cat(lambda s: s.windows[m], np.int8) for m in methods
                       if scores and all(m in s.windows for s in scores)},
                      cat(lambda s: (s.optical_offset if s.optical_offset is not None
                                     else np.full(len(s.candidate_distance), np.nan)), float),
                      cat(lambda s: (s.optical_offset_50 if s.optical_offset_50 is not None
                                     else np.full(len(s.candidate_distance), np.nan)), float),
                      {m: cat(lambda s: s.bounds.get(m, np.full(len(s.candidate_distance), np.nan)), float)
                       for m in methods})
