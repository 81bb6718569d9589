"""The board study's side lines: each square's sides fitted to a method's refined points (``lines``)."""
