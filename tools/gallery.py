"""The gallery's pictures, each made by one command (`make gallery`, or `python tools/gallery.py NAME...`).

    python tools/gallery.py                 # every picture into docs/gallery/ (and the README's docs/images/hero.png)
    python tools/gallery.py hero targets    # only these

Renders come from the shipped `quick` spec (640x512, the study's optics in pixels), rendered once into
runs/gallery/quick (resumable; only the images a picture needs); the board pair from the shipped Zhang set
and its twin spec; the report figures are the committed ones in docs/results/, scaled down. Every PNG is
written small (8-bit palette where it helps), well under 300 KB.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "gallery"
HERO = ROOT / "docs" / "images" / "hero.png"
RUNS = ROOT / "runs" / "gallery"

# quick spec indices: G1_T1 slots 0-19 are 15-34, G2/G3/G4 on T1 add 20 each, T2/T3/T4 at G1 follow
SLOT = 2                        # 86 cm
T1_G = {"G1": 15, "G2": 35, "G3": 55, "G4": 75}
TARGETS = {"T1": 15, "T2": 95, "T3": 115, "T4": 135}
DISTANCE_SLOTS = (0, 5, 10, 15, 19)   # 61, 124, 177, 248, 290 cm


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": 8, "savefig.dpi": 100})
    return plt


def _save(fig, path: Path) -> Path:
    """Save small: an 8-bit palette PNG (matplotlib's RGBA, quantised by Pillow when present)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, bbox_inches="tight", pad_inches=0.05)
    _plt().close(fig)
    try:
        from PIL import Image

        im = Image.open(path).convert("RGB").quantize(colors=128, method=Image.Quantize.MEDIANCUT)
        im.save(path, optimize=True)
    except ImportError:  # matplotlib depends on Pillow, so this is the exception
        pass
    print(f"{path.relative_to(ROOT)}: {path.stat().st_size // 1024} KB")
    return path


def _quick(indices) -> "object":
    """The quick spec's images ``indices``, rendered into runs/gallery/quick if not there yet."""
    from edgetruth.render import open_dataset
    from edgetruth.render.dataset.driver import render_spec

    d = RUNS / "quick"
    have = set()
    if (d / "manifest.json").exists():
        have = {s.index for s in open_dataset(d)}
    todo = sorted(set(indices) - have)
    if todo:
        render_spec("quick", d, only=todo, progress=False, announce=lambda *a, **k: None)
    return open_dataset(d)


def _sample(ds, index):
    return next(s for s in ds if s.index == index)


def _outline_xy(s) -> np.ndarray:
    return np.asarray(s.truth["outline"]["polyline_distorted_px"], float)


def _display(img: np.ndarray) -> np.ndarray:
    lo, hi = np.percentile(img, [0.5, 99.5])
    return np.clip((img - lo) / max(hi - lo, 1e-9), 0, 1)


def hero() -> Path:
    """A render, its exact outline, and a crop with two methods' points against the truth."""
    from edgetruth import locate

    s = _sample(_quick([TARGETS["T1"] + SLOT]), TARGETS["T1"] + SLOT)
    img = s.image.astype(float)
    poly = _outline_xy(s)
    plt = _plt()
    fig, (a, b) = plt.subplots(1, 2, figsize=(9.0, 3.6), gridspec_kw={"width_ratios": [1.25, 1]})
    a.imshow(_display(img), cmap="gray", interpolation="nearest")
    a.plot(*np.vstack([poly, poly[:1]]).T, color="#00d000", lw=1.0, label="exact outline")
    # the crop: around the middle of the outline's top side
    top = poly[np.argmin(poly[:, 1])]
    cx, cy = float(np.median(poly[:, 0])), float(top[1])
    x0, y0, w = int(cx - 4), int(cy - 3), 8
    a.add_patch(plt.Rectangle((x0 - 0.5, y0 - 0.5), w, w * 0.75, fill=False, ec="#ff3030", lw=1.5))
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    pad = 0.6 * (hi - lo).max()
    a.set_xlim(lo[0] - pad, hi[0] + pad)
    a.set_ylim(hi[1] + pad, lo[1] - pad)
    a.set_title(f"render: T1 at {s.truth['pose']['distance_m'] * 100:.0f} cm, its exact outline (green)", fontsize=8)
    a.set_axis_off()
    b.imshow(_display(img), cmap="gray", interpolation="nearest")
    # the exact outline in the crop: the zero level of its signed distance on a fine grid
    gx, gy = np.meshgrid(np.linspace(x0 - 0.5, x0 + w - 0.5, 241), np.linspace(y0 - 0.5, y0 + w * 0.75 - 0.5, 181))
    sd = s.outline.signed_distance(gx.ravel(), gy.ravel()).reshape(gx.shape)
    b.contour(gx, gy, sd, levels=[0.0], colors="#00d000", linewidths=1.5)
    cand = locate.candidates(img)
    for method, colour, marker in (("canny_pixel", "#ff7f0e", "s"), ("patch_psf_fit", "#1f77b4", "o")):
        p = locate.refine(img, cand, method)
        inside = (p.x > x0 - 0.5) & (p.x < x0 + w - 0.5) & (p.y > y0 - 0.5) & (p.y < y0 + w * 0.75 - 0.5)
        e = s.outline.signed_distance(p.x[inside], p.y[inside])
        label = f"{locate.METHODS[method].label}: RMSE {np.sqrt(np.mean(e ** 2)):.3f} px here"
        b.plot(p.x[inside], p.y[inside], marker, ms=7, mfc="none", mec=colour, mew=1.2, ls="none", label=label)
    b.plot([], [], color="#00d000", label="exact outline")
    b.set_xlim(x0 - 0.5, x0 + w - 0.5)
    b.set_ylim(y0 + w * 0.75 - 0.5, y0 - 0.5)
    b.legend(loc="lower center", fontsize=7, framealpha=0.85)
    b.set_title("crop: subpixel points against the exact outline", fontsize=8)
    b.set_xticks([])
    b.set_yticks([])
    return _save(fig, HERO)


def targets() -> Path:
    """T1-T4 (black matte square, black matte circle, gray matte square, glossy black square) at 86 cm."""
    ds = _quick([i + SLOT for i in TARGETS.values()])
    plt = _plt()
    fig, axes = plt.subplots(1, 4, figsize=(10, 2.3))
    names = {"T1": "T1 black matte square", "T2": "T2 black matte circle", "T3": "T3 gray matte square",
             "T4": "T4 glossy black square"}
    for ax, (t, i) in zip(axes, TARGETS.items()):
        s = _sample(ds, i + SLOT)
        ax.imshow(s.image, cmap="gray", interpolation="nearest")
        ax.set_title(names[t], fontsize=8)
        ax.set_axis_off()
    return _save(fig, OUT / "targets.png")


def defocus() -> Path:
    """T1 across 61-290 cm (focus at 150 cm): crops of one corner, 24 px wide, at each distance."""
    idx = [TARGETS["T1"] + k for k in DISTANCE_SLOTS]
    ds = _quick(idx)
    plt = _plt()
    fig, axes = plt.subplots(1, len(idx), figsize=(10, 2.4))
    for ax, i in zip(axes, idx):
        s = _sample(ds, i)
        corner = np.asarray(s.truth["outline"]["distorted_px"], float)[0]
        x, y = int(round(corner[0])), int(round(corner[1]))
        h = 12
        crop = s.image[max(y - h, 0):y + h, max(x - h, 0):x + h].astype(float)
        ax.imshow(crop, cmap="gray", interpolation="nearest")
        r = s.truth.get("defocus_radius_px")
        extra = f", defocus r {r:.2f} px" if isinstance(r, (int, float)) else ""
        ax.set_title(f"{s.truth['pose']['distance_m'] * 100:.0f} cm{extra}", fontsize=8)
        ax.set_axis_off()
    return _save(fig, OUT / "defocus.png")


def noise() -> Path:
    """T1 at 86 cm at the four SNR levels G1-G4 (same radiance render, less light to the sensor)."""
    idx = [i + SLOT for i in T1_G.values()]
    ds = _quick(idx)
    plt = _plt()
    fig, axes = plt.subplots(1, 4, figsize=(10, 2.4))
    for ax, (g, i) in zip(axes, T1_G.items()):
        s = _sample(ds, i + SLOT)
        corner = np.asarray(s.truth["outline"]["distorted_px"], float)[0]
        x, y = int(round(corner[0])), int(round(corner[1]))
        crop = s.image[y - 16:y + 16, x - 16:x + 16].astype(float)
        ax.imshow(crop, cmap="gray", interpolation="nearest")
        ax.set_title(g, fontsize=8)
        ax.set_axis_off()
    return _save(fig, OUT / "noise.png")


def psf_mtf() -> Path:
    """The quick camera's lens PSF (the model's OTF without the pixel, inverted) and its MTF, centre and corner."""
    from edgetruth.render import load_spec
    from edgetruth.render.optics.psf import psf_params

    cam = load_spec("quick").jobs[0].camera
    p = psf_params(cam)
    plt = _plt()
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3.2), gridspec_kw={"width_ratios": [1, 1.4]})
    n, step = 256, 1 / 16  # PSF sampled every 1/16 px over 16 px
    nu = np.fft.fftfreq(n, d=step)
    nx, ny = np.meshgrid(nu, nu)
    psf = np.fft.fftshift(np.real(np.fft.ifft2(p.otf(nx, ny, 0.0, pixel=False))))
    ext = n * step / 2
    a.imshow(psf / psf.max(), cmap="magma", extent=(-ext, ext, ext, -ext), interpolation="bilinear")
    a.set_xlim(-3, 3)
    a.set_ylim(3, -3)
    a.set_xlabel("px")
    a.set_title("lens PSF at the centre (Airy x aberration)", fontsize=8)
    f = np.linspace(0, 0.5, 201)
    for field, label in ((0.0, "centre"), (1.0, "corner")):
        b.plot(f, np.abs(p.otf(f, 0 * f, field)), label=f"lens + pixel, {label}")
    b.plot(f, np.abs(p.otf(f, 0 * f, 0.0, pixel=False)), ls="--", label="lens alone, centre")
    b.axhline(0.5, color="gray", lw=0.5)
    b.set_xlabel("cycles / px")
    b.set_ylabel("MTF")
    b.set_ylim(0, 1.02)
    b.legend(fontsize=7)
    b.set_title(f"MTF in focus ({cam.name} camera, f/{cam.f_number:g})", fontsize=8)
    return _save(fig, OUT / "psf_mtf.png")


def board_twin() -> Path:
    """Zhang's first calibration photo (shipped, BSD-2-Clause) beside its digital twin's render."""
    from edgetruth.image_io import read_gray
    from edgetruth.render import open_dataset
    from edgetruth.render.dataset.driver import render_spec
    from edgetruth.resources import real_set

    d = RUNS / "zhang1998_twin"
    if not (d / "manifest.json").exists() or not len(open_dataset(d)):
        render_spec("zhang1998_twin", d, only=[0], progress=False, announce=lambda *a, **k: None)
    twin = next(iter(open_dataset(d)))
    photo = read_gray(real_set("zhang1998") / "CalibIm1.png")
    plt = _plt()
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.5))
    a.imshow(photo, cmap="gray", interpolation="nearest")
    a.set_title("Zhang 1998, photo 1 (real)", fontsize=8)
    b.imshow(twin.image, cmap="gray", interpolation="nearest")
    b.set_title("its digital twin (edgetruth render, exact truth)", fontsize=8)
    for ax in (a, b):
        ax.set_axis_off()
    return _save(fig, OUT / "board_twin.png")


def report_figures() -> list[Path]:
    """The full ranging study's main figures, scaled down from docs/results/ranging_full/figures."""
    from PIL import Image

    out = []
    src = ROOT / "docs" / "results" / "ranging_full" / "figures"
    for name in ("fig10_rmse_vs_distance.png", "fig_points_distance.png", "fig11_snr_groups.png",
                 "fig12_targets.png"):
        im = Image.open(src / name).convert("RGB")
        im.thumbnail((900, 600))
        path = OUT / f"report_{name}"
        path.parent.mkdir(parents=True, exist_ok=True)
        im.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
        print(f"{path.relative_to(ROOT)}: {path.stat().st_size // 1024} KB")
        out.append(path)
    return out


PICTURES = {"hero": hero, "targets": targets, "defocus": defocus, "noise": noise, "psf_mtf": psf_mtf, "board_twin": board_twin,
            "report": report_figures}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("names", nargs="*", help=f"pictures to make: {', '.join(PICTURES)} (default: all)")
    args = ap.parse_args(argv)
    bad = [n for n in args.names if n not in PICTURES]
    if bad:
        ap.error(f"unknown picture {bad[0]!r}; choose from {', '.join(PICTURES)}")
    for name in args.names or PICTURES:
        PICTURES[name]()
    return 0


if __name__ == "__main__":
    sys.exit(main())
