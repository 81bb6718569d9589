"""evaluate: statistics, the Cramér–Rao bound, studies and reports."""
