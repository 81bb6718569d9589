"""Camera and optics: what the lens does to light before it reaches the sensor.

- ``camera``: intrinsics, thin-lens aperture, distortion, PSF and falloff of one camera (TOML).
- ``distortion``: Brown-Conrady (OpenCV's 5 coefficients), forward and inverse.
- ``psf``, ``mtf``: the point-spread function as sampled and its analytic MTF.
- ``prediction``: MTF50 and relative illumination a camera predicts at a field height.
- ``lens_sensor``: the Mitsuba sensor plugin that samples all of the above.
- ``optical_edge``: where these optics put an edge, beside the geometric outline.

Imports only render's floor (``schema``, ``edge_truth``), never the scene or the dataset.
"""
