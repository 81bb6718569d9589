"""pycalib's GoPro ChArUco photos 00000001-00000009 (nbhr/pycalib data/charuco); provenance in ../README.md (Apache-2.0)."""
