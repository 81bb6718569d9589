"""Zhang (1998) calibration photos; provenance in ../README.md, licence LICENSE-imagingbook."""
