"""The scene: what stands in front of the camera, posed and rendered, with its exact truth.

- ``shapes``, ``targets``, ``materials``, ``lights``: the catalogue, presets, materials and lights.
- ``pose``: where the board sits; ``mitsuba_scene``: the Mitsuba scene, loaded once and re-posed.
- ``outline``, ``ground_truth``: the exact distorted outlines, corners and squares (the truth).
- ``edge_band``, ``edge_coverage``: the pixels near outlines, re-rendered or integrated exactly.
- ``emissive``: emissive shapes on black, whose exact image is known analytically.

Imports the optics below it, never the sensor or the dataset.
"""
