"""A user's method, as a plug-in module would define it (used by tests/cli/test_plugins.py)."""
import numpy as np

from edgetruth import locate
from edgetruth.locate.profiles import profile_offsets, sample_profiles


@locate.register("user_gradient_centroid", label="UserGradientCentroid")
def user_gradient_centroid(image, cand):
    """Centroid of the positive profile differences along the normal."""
    prof = sample_profiles(image, cand)
    g = np.clip(np.diff(prof, axis=1), 0, None)
    t = profile_offsets()[:-1] + 0.5
    mu = (g * t).sum(1) / np.maximum(g.sum(1), 1e-12)
    return locate.Refinement.from_offset(cand, mu, converged=g.sum(1) > 0)
