"""One module per method (or method family); each registers itself via ``locate.registry.register``."""
