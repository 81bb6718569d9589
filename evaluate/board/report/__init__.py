"""The board study's files (``files``: report.md, the CSV tables, calibrations) and figures (``figures``)."""
