"""Regenerate sfrmat5_reference.json (and the shipped edge crop) -- not a test, run by hand.

    python make_reference.py --exe /tmp/sfrref/run_sfrmat5 \
        --mtfmapper-jpg single_roi_input.jpg [--burns-dir DIR] --out .

``--exe``: run_sfrmat5.cpp (this folder) compiled against the C++ port of sfrmat5
(github.com/t-kuha/sfrmat5, cpp/sfrmat5.cpp + cpp/sfrmat5.h) and Eigen 3.4, see PROVENANCE.md.
It reads a raw float64 image and prints the port's SFR50, edge polynomial and SFR curve as JSON.
``--burns-dir``: a folder holding sfrmat5's Test_edge1.bmp and Test_edge1_mono.tif and
nssfr_sfrmat5's h_edge.tif (not redistributable here: their numbers only are stored).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import tempfile
from pathlib import Path

import cv2
import numpy as np

LUMA = (0.213, 0.715, 0.072)  # sfrmat5's default luminance weights (R, G, B)
FREQS = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5)
CROP_COLS = (28, 208)  # mosaic columns kept (even start: the CFA phase is unchanged)


def sfrmat5(exe: str, img: np.ndarray, npol: int) -> dict:
    img = np.ascontiguousarray(img, dtype=np.float64)
    with tempfile.NamedTemporaryFile(suffix=".raw", delete=False) as f:
        f.write(np.array(img.shape, dtype=np.int32).tobytes())
        f.write(img.tobytes())
        path = f.name
    try:
        out = subprocess.run([exe, path, str(npol)], capture_output=True, text=True, check=True).stdout
    finally:
        os.unlink(path)
    d = json.loads(out)
    freq, sfr = np.array(d["freq"]), np.array(d["sfr"])
    # sfrmat5 turns a horizontal edge vertical first (rotatev2: means of rows 3 and end-3 vs columns)
    nn = 3
    rotated = abs(img[-1 - nn, :].mean() - img[nn - 1, :].mean()) > abs(img[:, -1 - nn].mean() - img[:, nn - 1].mean())
    return {"npol": npol, "mtf50_cy_px": round(d["sfr50"], 6),
            "poly_coefficients": d["fitme"],
            "edge_angle_deg_abs": round(float(abs(np.degrees(np.arctan(d["fitme"][-2])))), 4) if npol == 1 else None,
            "rotated_by_sfrmat5": bool(rotated),
            "sfr_at": {f"{nu:.2f}": round(float(np.interp(nu, freq, sfr)), 5) for nu in FREQS}}


def luminance(path: Path) -> np.ndarray:
    a = cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.float64)
    if a.ndim == 3:
        rgb = a[..., :3][..., ::-1]
        return LUMA[0] * rgb[..., 0] + LUMA[1] * rgb[..., 1] + LUMA[2] * rgb[..., 2]
    return a


def superpixel(mosaic: np.ndarray) -> np.ndarray:
    """Mean of each 2x2 Bayer cell: a gray image at half resolution (what the tests analyse)."""
    h, w = mosaic.shape
    return mosaic[:h // 2 * 2, :w // 2 * 2].astype(np.float64).reshape(h // 2, 2, w // 2, 2).mean(axis=(1, 3))


def entry(exe, name, img, source, note):
    return {"name": name, "source": source, "note": note, "shape": list(img.shape),
            "sfrmat5": [sfrmat5(exe, img, 1), sfrmat5(exe, img, 5)]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--exe", required=True)
    ap.add_argument("--mtfmapper-jpg", required=True)
    ap.add_argument("--burns-dir")
    ap.add_argument("--out", default=".")
    a = ap.parse_args()
    out = Path(a.out)
    jpg = Path(a.mtfmapper_jpg)
    mosaic = cv2.imread(str(jpg), cv2.IMREAD_GRAYSCALE)
    crop = mosaic[:, CROP_COLS[0]:CROP_COLS[1]]
    cv2.imwrite(str(out / "mtfmapper_single_roi_crop.png"), crop, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    crop = cv2.imread(str(out / "mtfmapper_single_roi_crop.png"), cv2.IMREAD_UNCHANGED)  # as the tests read it
    edges = [entry(a.exe, "mtfmapper_superpixel", superpixel(crop), "mtfmapper_single_roi_crop.png",
                   "2x2 mean of the Bayer mosaic crop (shipped)")]
    for (i, j), ch in {(0, 0): "R", (0, 1): "G1", (1, 0): "G2", (1, 1): "B"}.items():
        edges.append(entry(a.exe, f"mtfmapper_cfa_{ch}", crop[i::2, j::2].astype(float),
                           "mtfmapper_single_roi_crop.png", f"CFA sub-mosaic rows {i}::2, cols {j}::2 (shipped)"))
    if a.burns_dir:
        d = Path(a.burns_dir)
        luma = "sfrmat5 luminance (0.213, 0.715, 0.072)"
        for fname, name, note in [("Test_edge1.bmp", "sfrmat5_Test_edge1_lum", luma),
                                  ("Test_edge1_mono.tif", "sfrmat5_Test_edge1_mono", "as read"),
                                  ("h_edge.tif", "nssfr_h_edge_lum", luma)]:
            p = d / fname
            e = entry(a.exe, name, luminance(p), fname + " (not shipped)", note)
            e["sha256"] = hashlib.sha256(p.read_bytes()).hexdigest()
            edges.append(e)
        p = d / "Test_edge1.bmp"  # the port's own test program reports the red record's SFR50
        rgb = cv2.imread(str(p), cv2.IMREAD_COLOR)[..., ::-1].astype(float)
        e = entry(a.exe, "sfrmat5_Test_edge1_red", rgb[..., 0], "Test_edge1.bmp (not shipped)",
                  "red record: the number test_sfrmat5 prints as SFR50")
        e["sha256"] = hashlib.sha256(p.read_bytes()).hexdigest()
        edges.append(e)
    doc = {"reference": "sfrmat5 C++ port, github.com/t-kuha/sfrmat5 @ e422be17323cdb4335460feb8d429f8129d86813",
           "settings": "Tukey window (wflag 0), del = 1 (cy/px), nbin 4; "
                       "npol 1 (ISO 12233:2017 line) and 5 (sfrmat5 default)",
           "mtfmapper_jpg_sha256": hashlib.sha256(jpg.read_bytes()).hexdigest(),
           "crop_cols": list(CROP_COLS), "edges": edges}
    (out / "sfrmat5_reference.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
