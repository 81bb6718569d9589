"""Datasets: a spec in, a resumable directory of images with exact truth out.

- ``spec``, ``spec_doc``: the TOML spec, validated, and docs/spec.md generated from its key tables.
- ``image``: one image of a spec (scene, pose, render, sensor, truth), a pure function of (spec, index).
- ``task``, ``driver``, ``journal``: workers, the resumable driver loop and its journal.
- ``files``, ``reader``: the files written and reading them back (``open_dataset``).

The top of render's stages: spec -> scene -> camera -> sensor -> files.
"""
