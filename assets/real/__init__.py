"""Real photo sets shipped with their provenance and licences (see README.md beside this file)."""
