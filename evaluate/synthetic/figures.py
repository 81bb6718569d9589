"""Figures of the synthetic study, like the seed's Figures 4-7 (matplotlib, Agg)."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from edgetruth.evaluate import method_order as mo  # noqa: E402
from edgetruth.render.synthetic.scenarios import SCENARIOS  # noqa: E402

WINDOWS = (5, 7, 9, 11)


def _save(fig, path: Path) -> str:
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=110, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return path.name


def window_shares(tables: dict, out: Path) -> str:
    rows = [r for r in tables["windows"] if r["model"] == "4p" and r["scenario"] != "all"]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    bottom = np.zeros(len(rows))
    for k in WINDOWS:
        v = np.array([100 * r[f"w{k}"] for r in rows])
        ax.bar([r["scenario"] for r in rows], v, bottom=bottom, label=f"{k}-point")
        bottom += v
    ax.set_ylabel("share of points (%)")
    ax.set_title("Dynamic window selection (4P thresholds), per scenario")
    ax.legend(ncol=4, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12))
    return _save(fig, out / "fig4_window_shares.png")


def sensitivity(tables: dict, out: Path) -> str:
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for model, rs in tables["sensitivity"].items():
        ax.plot([r["delta"] for r in rs], [r["rmse"] for r in rs], "o-", label=f"dynamic ERF {model.upper()}")
    ax.set_xlabel("threshold offset δ")
    ax.set_ylabel("RMSE (px)")
    ax.set_title("Threshold sensitivity (τ_i + δ)")
    ax.grid(alpha=0.3)
    ax.legend()
    return _save(fig, out / "fig5_threshold_sensitivity.png")


def boxplots(data, out: Path) -> str:
    methods = [m for m in data.methods if not m.startswith("erf")]
    fig, ax = plt.subplots(figsize=(9, 4))
    common = data.common if data.common is not None else np.ones(data.scenario.size, bool)
    ax.boxplot([np.abs(data.errors[m][common]) for m in methods], showfliers=False)
    ax.set_xticks(range(1, len(methods) + 1), [mo.label(m) for m in methods], rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("|error| (px), whiskers 1.5 IQR")
    ax.set_title(f"Localisation error on the common subset ({int(common.sum())} points every method refines)")
    ax.grid(axis="y", alpha=0.3)
    return _save(fig, out / "fig6_error_boxplots.png")


def per_scenario(tables: dict, out: Path) -> str:
    rows = [r for r in tables["per_scenario"] if not r["method"].startswith("erf")]
    fig, ax = plt.subplots(figsize=(10, 4))
    width = 0.8 / len(SCENARIOS)
    x = np.arange(len(rows))
    for i, sc in enumerate(SCENARIOS):
        ax.bar(x + i * width, [r[f"{sc}_rmse_common"] for r in rows], width, label=sc)
    ax.set_xticks(x + 0.4 - width / 2, [mo.label(r["method"]) for r in rows], rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("RMSE (px)")
    ax.set_yscale("log")
    ax.set_title("RMSE per scenario (common subset)")
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    return _save(fig, out / "fig7_rmse_per_scenario.png")
