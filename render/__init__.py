"""edgetruth.render: images with exact ground truth.

Sub-packages by stage, imports one way (dataset -> scene -> optics; sensor beside optics):

- ``synthetic``: analytic edges (Ideal, Slope, Texture, Asymmetric) integrated exactly over
  each pixel's area, the true edge as truth.
- ``optics``: the camera (intrinsics, thin lens, distortion, PSF, falloff) and what it predicts.
- ``scene``: targets, shapes, materials, lights, poses, the Mitsuba scene and its exact truth.
- ``sensor``: the EMVA 1288 sensor and the image pipeline.
- ``dataset``: specs, the resumable driver, the files and reading them back
  (``open_dataset(DIR)``).

The floor under them: ``schema`` (key tables), ``variants`` (Mitsuba's variant) and
``edge_truth`` (signed distance to a curve). Tools on top: ``bench``, ``mc_noise``, ``testing``.

Only the light API is imported here; Mitsuba loads when something renders.
"""
from edgetruth.render.dataset.reader import Dataset, Sample, open_dataset
from edgetruth.render.dataset.spec import Spec, load_spec

__all__ = ["Dataset", "Sample", "Spec", "load_spec", "open_dataset"]
