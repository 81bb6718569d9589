"""The sensor: from rendered radiance to the file's pixels.

- ``linear_model``: the EMVA 1288 linear camera model (photons, electrons, DN, DSNU/PRNU).
- ``pipeline``: demosaicing, gray, sRGB, JPEG.
- ``capture``: one image from its radiance through both.

Imports only render's floor (``schema``).
"""
