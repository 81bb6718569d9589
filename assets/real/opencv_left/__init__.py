"""OpenCV sample chessboard photos left01-14; provenance in ../README.md (Apache-2.0)."""
