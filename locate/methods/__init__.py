"""One module per method (or method family); each registers itself via ``edgetruth.locate.registry.register``."""
