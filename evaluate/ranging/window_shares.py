"""Which window the dynamic ERF method picks on rendered targets (5/7/9/11 samples), per image and overall.

The same chain as the ranging study up to the refinement (target finding on the image, its
boundary candidates, ``dynamic_erf_4p`` with the shipped thresholds), without calibration or
undistortion: the window depends on the edge's blur, which the lens model sets.

    python -m edgetruth.evaluate.ranging.window_shares runs/study [more datasets...] [--group G1_T1]

``beside_section``: the report's table of a run's window shares (its ``render_points_summary.csv``)
beside the full study's (``FULL_STUDY_SHARES``), which `edgetruth run` (the quick study) prints so
that the minutes-long run can be read against the hour-long one.
"""
from __future__ import annotations

import csv
import sys

import numpy as np

from edgetruth import locate
from edgetruth.evaluate.design import interval_label
from edgetruth.evaluate.method_order import label as method_label
from edgetruth.evaluate.target import target_candidates
from edgetruth.render.dataset.reader import open_dataset


WINDOWS = (5, 7, 9, 11)

#: The full study's window shares on its scored points (5, 7, 9, 11 samples, n points), per design cell
#: (base = G1_T1; G1 and T1 are the base cell) and dynamic method (``_camera``: the thresholds calibrated
#: for the camera on the disjoint ``thresholds`` renders).  Stated from the committed results: the
#: ``interval == all`` rows of docs/results/ranging_full/render_points_summary.csv (`edgetruth run --study
#: full`, 50 pose slots x 7 cells at 1280x1024; tests/evaluate/ranging/test_window_shares_beside.py checks
#: these digits against that file).  A wheel has no docs/: hence the constants.
FULL_STUDY_SOURCE = "docs/results/ranging_full (`edgetruth run --study full`: 50 pose slots x 7 cells, 1280x1024)"
FULL_STUDY_SHARES = {
    ("base", "dynamic_erf_2p"): (0.9069, 0.0931, 0.0000, 0.0000, 29280),
    ("base", "dynamic_erf_2p_camera"): (0.0000, 1.0000, 0.0000, 0.0000, 29280),
    ("base", "dynamic_erf_4p"): (0.9654, 0.0346, 0.0000, 0.0000, 29280),
    ("base", "dynamic_erf_4p_camera"): (0.0000, 0.0001, 0.0143, 0.9856, 29280),
    ("G2", "dynamic_erf_2p"): (0.8715, 0.1284, 0.0000, 0.0000, 29280),
    ("G2", "dynamic_erf_2p_camera"): (0.0000, 1.0000, 0.0000, 0.0000, 29280),
    ("G2", "dynamic_erf_4p"): (0.9322, 0.0672, 0.0006, 0.0000, 29280),
    ("G2", "dynamic_erf_4p_camera"): (0.0000, 0.0000, 0.0072, 0.9928, 29280),
    ("G3", "dynamic_erf_2p"): (0.7937, 0.2025, 0.0038, 0.0000, 29280),
    ("G3", "dynamic_erf_2p_camera"): (0.0000, 0.9998, 0.0000, 0.0002, 29280),
    ("G3", "dynamic_erf_4p"): (0.8774, 0.1153, 0.0073, 0.0000, 29280),
    ("G3", "dynamic_erf_4p_camera"): (0.0000, 0.0002, 0.0028, 0.9970, 29280),
    ("G4", "dynamic_erf_2p"): (0.5741, 0.3994, 0.0258, 0.0007, 29280),
    ("G4", "dynamic_erf_2p_camera"): (0.0000, 0.9940, 0.0000, 0.0060, 29280),
    ("G4", "dynamic_erf_4p"): (0.7279, 0.2339, 0.0367, 0.0015, 29280),
    ("G4", "dynamic_erf_4p_camera"): (0.0000, 0.0000, 0.0012, 0.9988, 29280),
    ("T2", "dynamic_erf_2p"): (0.9109, 0.0891, 0.0000, 0.0000, 28420),
    ("T2", "dynamic_erf_2p_camera"): (0.0000, 1.0000, 0.0000, 0.0000, 28420),
    ("T2", "dynamic_erf_4p"): (0.9722, 0.0278, 0.0000, 0.0000, 28420),
    ("T2", "dynamic_erf_4p_camera"): (0.0000, 0.0000, 0.0051, 0.9948, 28420),
    ("T3", "dynamic_erf_2p"): (0.8422, 0.1569, 0.0009, 0.0000, 29280),
    ("T3", "dynamic_erf_2p_camera"): (0.0000, 0.9999, 0.0000, 0.0001, 29280),
    ("T3", "dynamic_erf_4p"): (0.9106, 0.0867, 0.0026, 0.0000, 29280),
    ("T3", "dynamic_erf_4p_camera"): (0.0000, 0.0000, 0.0034, 0.9966, 29280),
    ("T4", "dynamic_erf_2p"): (0.8612, 0.1385, 0.0002, 0.0000, 29122),
    ("T4", "dynamic_erf_2p_camera"): (0.0000, 1.0000, 0.0000, 0.0000, 29122),
    ("T4", "dynamic_erf_4p"): (0.9354, 0.0641, 0.0005, 0.0000, 29122),
    ("T4", "dynamic_erf_4p_camera"): (0.0000, 0.0001, 0.0057, 0.9942, 29122),
}


def image_window_counts(image: np.ndarray, method: str = "dynamic_erf_4p") -> dict[int, int]:
    tc = target_candidates(np.asarray(image, np.float64))
    pts = locate.refine(tc.crop, tc.candidates, method)
    w = np.asarray(pts.window)
    return {k: int(np.sum(w == k)) for k in WINDOWS}


def window_shares(dataset_dirs, method: str = "dynamic_erf_4p", groups=None) -> dict:
    """{"total": {5: share, ...}, "by_interval": {"50-100": {...}, ...}, "n_points": N, "n_images": M}."""
    total = dict.fromkeys(WINDOWS, 0)
    by_interval: dict = {}
    n_images = 0
    for d in dataset_dirs:
        for s in open_dataset(d).targets():
            if groups and s.group not in groups:
                continue
            counts = image_window_counts(s.image, method)
            key = interval_label(100 * float(s.truth["true_distance_m"]))
            acc = by_interval.setdefault(key, dict.fromkeys(WINDOWS, 0))
            for k, v in counts.items():
                total[k] += v
                acc[k] += v
            n_images += 1
    n = sum(total.values())

    def shares(c):
        m = max(sum(c.values()), 1)
        return {k: v / m for k, v in c.items()}
    return {"total": shares(total), "by_interval": {k: shares(v) for k, v in sorted(by_interval.items())},
            "n_points": n, "n_images": n_images, "method": method}


def summary_shares(path) -> dict:
    """{(cell, method): (share5, share7, share9, share11, n_points)} of a ``render_points_summary.csv``
    (its ``interval == all`` rows with window shares; cell: ``base`` or a level such as ``G2``)."""
    out = {}
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            if r.get("interval") != "all" or not r.get("window5_share"):
                continue
            cell = "base" if r["cell"] == "base" else r["level"]
            out[(cell, r["method"])] = tuple(float(r[f"window{w}_share"]) for w in WINDOWS) + (int(r["n_points"]),)
    return out


def beside_section(summary_csv, reference: dict | None = None, source: str = FULL_STUDY_SOURCE,
                   label: str = "this run") -> list[str]:
    """Markdown: the window shares of ``summary_csv`` beside ``reference`` (default: the full study's), per
    dynamic method and design cell both have; [] when they share none."""
    ref = FULL_STUDY_SHARES if reference is None else reference
    mine = summary_shares(summary_csv)
    keys = [k for k in ref if k in mine]  # the reference's order: base, G2-G4, T2-T4, per method
    if not keys:
        return []
    keys.sort(key=lambda k: (k[1], list(dict.fromkeys(c for c, _ in ref)).index(k[0])))
    pct = lambda v: f"{100 * v:.1f} %"  # noqa: E731
    body = ["| method | cell | " + " | ".join(f"{w} ({label})" for w in WINDOWS) + " | "
            + " | ".join(f"{w} (full study)" for w in WINDOWS) + f" | points ({label} / full study) |",
            "|" + "---|" * (3 + 2 * len(WINDOWS))]
    for cell, m in keys:
        a, b = mine[(cell, m)], ref[(cell, m)]
        body.append(f"| {method_label(m)} | {'base (G1_T1)' if cell == 'base' else cell} | "
                    + " | ".join(pct(v) for v in a[:4]) + " | " + " | ".join(pct(v) for v in b[:4])
                    + f" | {a[4]:,} / {b[4]:,} |")
    return ["", f"## Window shares: {label} beside the full study", "",
            f"The dynamic methods' windows on the scored points of {label}, per design cell, beside the full "
            f"study's ({source}).  The quick camera keeps the study camera's optics in pixels (the same PSF, "
            "MTF50 and defocus disk in px: docs/optics.md, \"The quick camera\"), so the shares should agree to "
            "within the sampling of fewer, smaller targets.", ""] + body


def main(argv: list[str]) -> int:  # pragma: no cover - a thin printer
    groups = [argv[i + 1] for i, a in enumerate(argv) if a == "--group"]
    dirs = [a for i, a in enumerate(argv) if a != "--group" and (i == 0 or argv[i - 1] != "--group")]
    r = window_shares(dirs, groups=groups or None)
    fmt = lambda s: "  ".join(f"{k}: {100 * v:5.1f} %" for k, v in s.items())  # noqa: E731
    print(f"{r['method']} window shares over {r['n_images']} images, {r['n_points']} points: {fmt(r['total'])}")
    for k, s in r["by_interval"].items():
        print(f"  {k} cm: {fmt(s)}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main(sys.argv[1:]))
