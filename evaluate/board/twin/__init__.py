"""A board's digital twin: ``derive.py`` measures on the photos what a twin needs and writes its camera and scene
(``edgetruth twin``), ``study.py`` renders a twin beside its photos and runs the board study on both (``edgetruth
study twin``), ``report.py`` writes the side-by-side report; the measurements they need (photon transfer, lens
shading, the JPEG's blur and noise, the blur's inverse, the board's flatness) each have a module here."""
