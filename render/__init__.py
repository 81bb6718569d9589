"""edgetruth.render: images with exact ground truth.

- Analytic edges (``analytic``, ``synthetic``, ``edge_truth``): Ideal, Slope, Texture and
  Asymmetric edge images integrated exactly over each pixel's area, the true edge as truth.
- Physically-based renders (``spec``, ``camera``, ``sensor``, ``mitsuba_scene``, ``dataset``):
  Mitsuba 3 renders of calibrated targets and checkerboards through a thin-lens camera with
  exact distortion and an EMVA 1288 sensor, written as resumable datasets.
- Reading them back: ``open_dataset(DIR)`` (``reader``).

Only the light API is imported here; Mitsuba loads when something renders.
"""
from edgetruth.render.reader import Dataset, Sample, open_dataset
from edgetruth.render.spec import Spec, load_spec

__all__ = ["Dataset", "Sample", "Spec", "load_spec", "open_dataset"]
