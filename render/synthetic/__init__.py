"""Analytic synthetic edges (the study's §4.2-4.3): no renderer, exact truth.

- ``analytic``: edge images integrated exactly over each pixel's area.
- ``scenarios``: the Ideal, Slope, Texture and Asymmetric scenarios built on them.
"""
