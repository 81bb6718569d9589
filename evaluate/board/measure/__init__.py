"""One row of the board study and its figures: a method's side lines and corners on every photo (``rows``,
``grid_corners``), the per-row summary (``summary``) and paired comparisons between rows (``compare``)."""
