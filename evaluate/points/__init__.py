"""Per-point truth on renders: ``scores.py`` scores every method's points against the exact outline, ``report.py`` writes Tables E1-E4."""
