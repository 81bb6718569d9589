"""Footprints (locate/footprints.py): each method's declaration covers every pixel its answer depends on.

For every built-in method, on a noisy blurred line and circle: changing one pixel changes a
candidate's refined point only if the pixel is in the method's declared footprint for that
candidate (checked for every pixel within the footprint radius and a ring beyond it).  The
candidate (position, normal, Canny gradient) is given; the smoothed image a method reads
(``cand.smoothed``) is recomputed from the changed image.  SER-CIS's image-wide noise estimate is
fixed (``noise_sigma``): it is a property of the image, not of the candidate.
"""
import dataclasses

import cv2
import numpy as np
import pytest

from edgetruth import locate
from edgetruth.locate import footprints as FP
from tests.support.edge_scenes import make_edge, near_candidates, render

SHAPE = (40, 40)
OPTIONS = {"ser_cis": {"noise_sigma": 1.2}}
# patch_esf_fit (needs a camera's tables) has its footprint check in tests/locate/test_patch_esf_fit.py
VARIANTS = [(m, {}) for m in locate.METHODS if locate.METHODS[m].builtin and not locate.METHODS[m].needs_camera] + [
    ("pae2013", {"variant": "smoothed"}), ("pae2013", {"variant": "basic"}), ("glm1984", {"half": 3})]


def _scene(kind):
    edge = make_edge(kind, 2)
    if kind == "circle":
        from edgetruth.render.edge_truth import CircleEdge

        edge = CircleEdge(19.6, 20.3, 9.5, True)
    else:
        from edgetruth.render.edge_truth import StraightEdge

        edge = StraightEdge(19.7, 20.2, edge.angle_rad)
    img = render(SHAPE, edge, 1.0, 0.01, rng=np.random.default_rng(7))
    cand = near_candidates(img, edge)
    inner = (cand.x >= 11) & (cand.x <= 28) & (cand.y >= 11) & (cand.y <= 28)
    return img, cand.subset(np.nonzero(inner)[0][::7][:2])


def _with_image(cand, img):
    smooth = cv2.GaussianBlur(img, (0, 0), sigmaX=cand.sigma_px, sigmaY=cand.sigma_px, borderType=cv2.BORDER_REFLECT)
    return dataclasses.replace(cand, smoothed=smooth)


@pytest.mark.slow
@pytest.mark.parametrize("method,opts", VARIANTS, ids=[f"{m}{'-' + '-'.join(map(str, o.values())) if o else ''}"
                                                       for m, o in VARIANTS])
def test_answer_depends_only_on_the_declared_footprint(method, opts):
    opts = {**OPTIONS.get(method, {}), **opts}
    checked = 0
    for kind in ("line", "circle"):
        img, cand = _scene(kind)
        masks = locate.METHODS[method].footprint_masks(cand, **opts)
        assert masks.shape == (len(cand), FP.SIZE, FP.SIZE)
        for i in range(len(cand)):
            one = cand.subset([i])
            base = locate.refine(img, _with_image(one, img), method, **opts)
            x, y = int(cand.x[i]), int(cand.y[i])
            reach = FP.RADIUS + 1
            for dy in range(-reach, reach + 1):
                for dx in range(-reach, reach + 1):
                    yy, xx = y + dy, x + dx
                    if not (0 <= yy < SHAPE[0] and 0 <= xx < SHAPE[1]):
                        continue
                    inside = abs(dy) <= FP.RADIUS and abs(dx) <= FP.RADIUS
                    if inside and masks[i, FP.RADIUS + dy, FP.RADIUS + dx]:
                        continue
                    pert = img.copy()
                    pert[yy, xx] += 3.0
                    got = locate.refine(pert, _with_image(one, pert), method, **opts)
                    same = (got.x[0] == base.x[0] and got.y[0] == base.y[0]
                            and got.converged[0] == base.converged[0])
                    assert same, f"{method}: pixel ({dx}, {dy}) from candidate {i} ({kind}) is read but not declared"
                    checked += 1
    assert checked > 300


def test_profile_footprint_is_the_bilinear_support():
    """The profile footprint holds exactly the pixels with a non-zero bilinear weight."""
    img, cand = _scene("line")
    m = FP.profile_masks(cand, 5)
    from edgetruth.locate.profiles import sample_profiles

    for i in range(len(cand)):
        one = cand.subset([i])
        base = sample_profiles(img, one)
        x, y = int(cand.x[i]), int(cand.y[i])
        for dy in range(-FP.RADIUS, FP.RADIUS + 1):
            for dx in range(-FP.RADIUS, FP.RADIUS + 1):
                pert = img.copy()
                pert[y + dy, x + dx] += 1.0
                changed = not np.array_equal(sample_profiles(pert, one), base)
                assert changed == m[i, FP.RADIUS + dy, FP.RADIUS + dx]


def test_undeclared_user_method_gets_the_whole_neighbourhood():
    rec = locate.Method("x", "x", "user", lambda image, cand: None)
    img, cand = _scene("line")
    assert rec.footprint_masks(cand).all()
