"""Figures of the board study (matplotlib, Agg), written atomically into ``figures/``."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from edgetruth.fileio import tmp_path  # noqa: E402

FIGURES = ("straightness.png", "calibration_rms.png", "side_length_error.png")


def save_figure(fig, path: Path) -> str:
    """Write ``fig`` to ``path`` atomically (a temporary sibling, then a rename) and close it; -> the file name."""
    tmp = tmp_path(path)
    fig.savefig(tmp, dpi=110, bbox_inches="tight")
    plt.close(fig)
    os.replace(tmp, path)
    return path.name


def _errbar(ax, y, value, ci, photos=None, **kw):
    """The value with its CI over units as error bars, and ``photos`` (the CI resampling photos) as a light band
    behind them."""
    if photos is not None and np.all(np.isfinite(photos)):
        ax.hlines(y, *photos, color=kw.get("color", "C0"), alpha=0.25, linewidth=6)
    lo, hi = ci
    err = None
    if np.isfinite(lo) and np.isfinite(hi):
        # clipped at 0: a value a hair outside its interval (OpenCV's RMS of exact corners, ~1e-6 px, against
        # the bootstrap of the residuals) draws no bar on that side
        err = np.maximum(np.array([[value - lo], [hi - value]]), 0.0)
    ax.errorbar([value], [y], xerr=err, fmt="o", capsize=3, **kw)


def straightness(summaries: list[dict], out: Path) -> str:
    rows = [s for s in summaries if np.isfinite(s["straightness_px"])]
    fig, ax = plt.subplots(figsize=(6.5, 0.32 * len(rows) + 1.4))
    for y, s in enumerate(rows):
        _errbar(ax, y, s["straightness_px"], s["straightness_ci"], s.get("straightness_ci_photos"), color="C0")
        ax.plot([s["straightness_median_px"]], [y], "|", color="C3", markersize=10)
    ax.set_yticks(range(len(rows)), [s["label"] for s in rows], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("RMS of side points about their TLS line (px)")
    ax.set_title("Straightness: pooled RMS, 95 % bootstrap CI over sides (band: over photos; | median side)",
                 fontsize=9)
    ax.grid(axis="x", alpha=0.3)
    return save_figure(fig, out / "straightness.png")


def calibration_rms(summaries: list[dict], out: Path) -> str:
    rows = [s for s in summaries if np.isfinite(s.get("calib_rms_px", np.nan))]
    fig, ax = plt.subplots(figsize=(6.5, 0.32 * len(rows) + 1.4))
    for y, s in enumerate(rows):
        _errbar(ax, y - 0.15, s["calib_rms_px"], s["calib_rms_ci"], s.get("calib_rms_ci_photos"), color="C0",
                label="calibration RMS" if y == 0 else None)
        _errbar(ax, y + 0.15, s["loo_rms_px"], s["loo_rms_ci"], s.get("loo_rms_ci_photos"), color="C1",
                label="leave-one-image-out RMS" if y == 0 else None)
    ax.set_yticks(range(len(rows)), [s["label"] for s in rows], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("reprojection RMS (px); 95 % bootstrap CI over corners (band: over photos)")
    ax.set_title("Zhang calibration (k1, k2) of each row's corners", fontsize=9)
    ax.grid(axis="x", alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    return save_figure(fig, out / "calibration_rms.png")


def side_length_error(summaries: list[dict], errors_px: dict, out: Path) -> str:
    rows = [s for s in summaries if s["row"] in errors_px]
    data = [np.asarray(errors_px[s["row"]], float) for s in rows]
    data = [d[np.isfinite(d)] for d in data]
    fig, ax = plt.subplots(figsize=(0.42 * len(rows) + 2.5, 4))
    ax.boxplot(data, showfliers=False)
    ax.set_xticks(range(1, len(rows) + 1), [s["label"] for s in rows], rotation=45, ha="right", fontsize=8)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_ylabel("measured − model (px at the side's scale)")
    ax.set_title("Side lengths in the board plane; whiskers 1.5 IQR", fontsize=9)
    ax.grid(axis="y", alpha=0.3)
    return save_figure(fig, out / "side_length_error.png")
