"""Shipped camera specs (``*.toml``)."""
