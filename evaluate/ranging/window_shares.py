"""Which window the dynamic ERF method picks on rendered targets (5/7/9/11 samples), per image and overall.

The same chain as the ranging study up to the refinement (target finding on the image, its
boundary candidates, ``dynamic_erf_4p`` with the shipped thresholds), without calibration or
undistortion: the window depends on the edge's blur, which the lens model sets.

    python -m edgetruth.evaluate.ranging.window_shares runs/study [more datasets...] [--group G1_T1]
"""
from __future__ import annotations

import sys

import numpy as np

WINDOWS = (5, 7, 9, 11)


def image_window_counts(image: np.ndarray, method: str = "dynamic_erf_4p") -> dict[int, int]:
    from edgetruth import locate
    from edgetruth.evaluate.ranging.target import target_candidates

    tc = target_candidates(np.asarray(image, np.float64))
    pts = locate.refine(tc.crop, tc.candidates, method)
    w = np.asarray(pts.window)
    return {k: int(np.sum(w == k)) for k in WINDOWS}


def window_shares(dataset_dirs, method: str = "dynamic_erf_4p", groups=None) -> dict:
    """{"total": {5: share, ...}, "by_interval": {"50-100": {...}, ...}, "n_points": N, "n_images": M}."""
    from edgetruth.evaluate.ranging.images import interval_label
    from edgetruth.render.reader import open_dataset

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
