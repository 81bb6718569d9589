"""BoofCV-Data Sony DSC-HX5V chessboard photos frame01-13; provenance in ../README.md (CC BY 4.0)."""
