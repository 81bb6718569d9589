"""The board study on real photographs (and on renders of boards): ``study.py`` drives it over its rooms, one per
stage: ``detect`` (the squares in a photo), ``sides`` (their side lines), ``measure`` (a method's row), ``calibrate``
(Zhang), ``tone`` (the photos' tone and photo model) and ``report``; ``model``, ``inputs`` and ``reference`` are
what they share.  Their digital twin: ``twin/``."""
