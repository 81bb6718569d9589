"""edgetruth: physically-based ground truth for subpixel edge localisation and monocular ranging.

Packages: ``render`` (images + exact ground truth), ``locate`` (edge point
refinement methods), ``evaluate`` (statistics, studies, reports); this package
holds the shared conventions and the command-line interface.
"""
__version__ = "0.2.0"
