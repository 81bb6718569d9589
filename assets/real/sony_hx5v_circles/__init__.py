"""BoofCV-Data Sony DSC-HX5V circle-grid photos image00000-00005; provenance in ../README.md (CC BY 4.0)."""
