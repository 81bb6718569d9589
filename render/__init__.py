"""render: images with exact ground truth.

- ``render.analytic`` / ``render.synthetic`` / ``render.edge_truth``: analytic
  edge images (Ideal, Slope, Texture, Asymmetric) integrated exactly over each
  pixel's area, with the true edge as ground truth.
- ``render.camera``, ``render.mitsuba_scene``, ``render.sensor``,
  ``render.dataset`` (and the modules they use): physically-based Mitsuba 3
  renders of calibrated targets and checkerboards with an EMVA 1288 sensor.

Submodules are imported explicitly (``from render.camera import Camera``).
"""
