"""Shipped data with provenance: entropy thresholds, camera specs (see ``edgetruth.resources``)."""
