"""Shipped render specs (``*.toml``), read with ``importlib.resources`` (see ``edgetruth.resources``)."""
