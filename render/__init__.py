"""Physically-based rendering of edge targets and calibration boards with exact ground truth.

Submodules are imported explicitly (``from render.camera import Camera``).
"""
