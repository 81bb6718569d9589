"""The hard-photo measurement: does the declared-target finder hold on room photos, and how far is Z from its floor?

``render.synthetic.room_photos`` draws photos with the failure modes of real phone photos and exact
truth.  Each photo goes through the photo pipeline (``photos.range_photo``: the declared-target finder
with the CSV row's priors, the methods, the size model, Z = fx S / l) with the true camera as its
calibration, and is scored:

- **found**: the refined target mask against the true outline's, IoU >= ``FOUND_IOU``; a miss is named
  (the image, its kind and distractors, the IoU, what was chosen instead);
- **ranging**: e = Z_hat - Z per method against the ranging-model floor of the same photos (the true
  outline through the same size model with the true fx: what tilt and lateral offset alone cost),
  RMSE(method) / RMSE(floor).

``python -m edgetruth.evaluate.ranging.hard_photos -n 64 -o DIR`` writes ``hard_photos.md`` and
``hard_photos.json`` there (docs/photos.md quotes a committed run).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from edgetruth.evaluate.calibration import Calibration
from edgetruth.evaluate.ranging.images import true_size_px
from edgetruth.evaluate.ranging.photos import PhotoRecord, range_photo
from edgetruth.evaluate.ranging.target_finder import contour_mask
from edgetruth.evaluate.report_format import num, table
from edgetruth.render.synthetic.room_photos import hard_set, render_room_photo


FOUND_IOU = 0.9
BENCH_METHODS = ("dynamic_erf_4p", "erf4p_fixed11", "canny_devernay", "ser_cis", "canny_pixel")


def true_calibration(truth: dict, image_shape):
    return Calibration.from_dict({"K": truth["K"], "dist_coeffs_opencv": [0.0] * 5,
                                  "image_size": [int(image_shape[1]), int(image_shape[0])]}, "room photo")


def floor_cm(truth: dict) -> float:
    """The ranging-model floor: 100 (fx S / l_true - Z) with l_true the size model on the true outline."""
    l_true = true_size_px({"outline": {"undistorted_px": truth["outline_px"]}, "target": {"shape": truth["shape"]}})
    return 100.0 * (truth["fx_px"] * truth["size_m"] / l_true - truth["true_distance_m"])


def record_for(name: str, truth: dict, path: str = "", roi=None, point=None, polarity: str | None = None):
    return PhotoRecord(0, name, path, 100.0 * truth["true_distance_m"], truth["size_m"], truth["shape"],
                       truth["kind"], polarity or truth["polarity"], truth["height_m"], roi, point)


def score_photo(image: np.ndarray, truth: dict, methods, polarity: str | None = None, name: str = "photo") -> dict:
    """One photo through the photo pipeline, scored against its truth (see the module docstring)."""
    rec = record_for(name, truth, polarity=polarity)
    t0 = time.process_time()
    res = range_photo(image, rec, true_calibration(truth, image.shape), list(methods), keep_points=False)
    cpu = time.process_time() - t0
    true_mask = contour_mask(np.asarray(truth["outline_px"]), image.shape)
    out = {"image": name, "kind": truth["kind"], "distance_cm": 100 * truth["true_distance_m"],
           "distractors": truth["design"]["distractors"], "polarity_asked": rec.polarity,
           "tilt_deg": float(np.hypot(truth["design"]["yaw_deg"], truth["design"]["pitch_deg"])),
           "floor_cm": floor_cm(truth), "cpu_s": cpu, "error": res.error}
    fin = res.region.get("finder") if res.region else None
    if fin is None:
        out.update(iou=0.0, found=False, chosen="nothing")
        return out
    found = contour_mask(np.asarray(fin["outline_px"], float), image.shape)  # the refined mask's boundary
    iou = float(np.count_nonzero(found & true_mask) / max(np.count_nonzero(found | true_mask), 1))
    out.update(iou=iou, found=iou >= FOUND_IOU, close=fin["close"], chosen=fin["chosen"],
               errors_cm={r["method"]: float(r["error_cm"]) for r in res.rows})
    return out


def run(n: int = 64, seed: int = 0, methods=BENCH_METHODS, auto_every: int = 2, progress: bool = False) -> dict:
    """``n`` hard photos (``room_photos.hard_set``); every ``auto_every``-th asks for polarity auto, the
    others declare it (both are what a CSV row may say)."""
    per = []
    for k, design in enumerate(hard_set(n, seed)):
        img, truth = render_room_photo(design)
        per.append(score_photo(img, truth, methods, polarity="auto" if k % auto_every == 0 else None,
                               name=f"room_{k:03d}"))
        if progress:
            print(k, per[-1]["kind"], per[-1]["found"], round(per[-1]["iou"], 3), flush=True)
    return summarise(per, list(methods))


def _rmse(v) -> float:
    v = np.asarray(v, float)
    return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")


def summarise(per: list[dict], methods: list[str]) -> dict:
    found = [p for p in per if p["found"]]
    floor = [p["floor_cm"] for p in found]
    ratios = {}
    for m in methods:
        e = [p["errors_cm"].get(m, np.nan) for p in found]
        ok = np.isfinite(e)
        ratios[m] = {"rmse_cm": _rmse(np.asarray(e)[ok]), "floor_rmse_cm": _rmse(np.asarray(floor)[ok]),
                     "excess_rmse_cm": _rmse((np.asarray(e) - np.asarray(floor))[ok]), "n": int(ok.sum())}
        ratios[m]["ratio"] = ratios[m]["rmse_cm"] / ratios[m]["floor_rmse_cm"]
    return {"n": len(per), "found": len(found), "found_frac": len(found) / max(len(per), 1),
            "failures": [{k: p.get(k) for k in ("image", "kind", "distance_cm", "distractors", "polarity_asked",
                                                "tilt_deg", "iou", "chosen", "error")} for p in per if not p["found"]],
            "close": [p["image"] for p in per if p.get("close")], "methods": ratios,
            "cpu_s_per_photo": float(np.mean([p["cpu_s"] for p in per])), "per_photo": per}


def markdown(s: dict) -> str:
    lines = ["# Hard room photos: target finding and ranging", "",
             f"{s['n']} analytic room photos (`render/synthetic/room_photos.py`, `hard_set`): dark squares and discs "
             "printed on white sheets, light sheets and cards with a drawing, text and a logo printed inside, on a "
             "wood-grain door with a handle, a tape measure, a second sheet and a soft shadow (each left out of a "
             "quarter), uneven light, JPEG, distances 50-300 cm, tilts up to 45 degrees; half ask for polarity auto.",
             "", f"**Target found** (refined mask IoU with the true outline >= {FOUND_IOU}): {s['found']} of {s['n']} "
             f"({100 * s['found_frac']:.1f} %).  Choice close (runner-up within 80 % of the best score): "
             f"{len(s['close'])} photos.", ""]
    if s["failures"]:
        lines += ["Failures:", ""] + [
            f"- {f['image']}: {f['kind']} at {f['distance_cm']:.0f} cm, tilt {f['tilt_deg']:.0f} deg, polarity "
            f"{f['polarity_asked']}, with {', '.join(f['distractors']) or 'nothing'}: IoU {f['iou']:.2f}"
            + (f"; chose a {f['chosen'].get('polarity')} region at {f['chosen'].get('bbox')}" if isinstance(
                f["chosen"], dict) else "") + (f" ({f['error']})" if f["error"] else "") for f in s["failures"]] + [""]
    else:
        lines += ["No failures.", ""]
    body = [[m, v["n"], num(v["rmse_cm"], 3), num(v["floor_rmse_cm"], 3), num(v["ratio"], 3),
             num(v["excess_rmse_cm"], 3)]
            for m, v in sorted(s["methods"].items(), key=lambda kv: kv[1]["ratio"])]
    lines += ["**Ranging** on the photos where the target was found, Z = fx S / l with the true fx: RMSE of "
              "e = Z_hat - Z against the ranging-model floor of the same photos (true outline, true fx), and the RMSE "
              "of e - floor (what the measurement adds to the model's own error; the floor is mostly the tilt's, "
              "which the size model does not undo, so the ratio alone says little).", "",
              table(["method", "photos", "RMSE (cm)", "floor RMSE (cm)", "ratio", "RMSE of e - floor (cm)"], body), "",
              f"CPU per photo (finding + {len(s['methods'])} methods): {s['cpu_s_per_photo']:.2f} s."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-n", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("-o", "--output", type=Path, required=True)
    a = ap.parse_args(argv)
    s = run(a.n, a.seed, progress=True)
    a.output.mkdir(parents=True, exist_ok=True)
    (a.output / "hard_photos.json").write_text(json.dumps({k: v for k, v in s.items()}, indent=1, default=str))
    (a.output / "hard_photos.md").write_text(markdown(s))
    print(markdown(s))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
