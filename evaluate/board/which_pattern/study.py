"""``edgetruth study pattern``: render the "which pattern?" spec (resumable), calibrate every cell with every
detector of its pattern against the exact truth, and write ``report.md``, ``results.json`` and the figures.

Each (cell, detector) is written to ``measured/`` as it finishes (keyed by the spec's identity), so a run that is
killed resumes: the renders where the render journal stopped, the measurements where ``measured/`` stops."""
from __future__ import annotations

import time
from pathlib import Path

from edgetruth import console
from edgetruth.errors import InputError
from edgetruth.evaluate.board.which_pattern.measure import DETECTORS, EDGE_METHOD, cells_of, measure_cell
from edgetruth.evaluate.board.which_pattern.report import write_report
from edgetruth.fileio import read_json, write_json
from edgetruth.render import open_dataset
from edgetruth.render.dataset.driver import render_spec
from edgetruth.render.dataset.spec import load_spec

DEFAULT_SPEC = "which_pattern"


def run_pattern_study(out_dir, spec: str = DEFAULT_SPEC, progress: bool = True, workers: int | None = None,
                      method: str = EDGE_METHOD, command: str | None = None) -> Path:
    """Render ``spec`` into ``out_dir/renders``, measure, report; -> the report's path."""
    t0 = time.perf_counter()
    out = Path(out_dir)
    sp = load_spec(spec)
    kinds = {g.kind for g in sp.groups}
    if not kinds & set(DETECTORS) or "target" in kinds:
        raise InputError(f"study pattern {spec}: the spec must show boards only (checkerboard, circles_grid or "
                         "charuco groups or design cells); use scenes/which_pattern.toml as a template")
    out.mkdir(parents=True, exist_ok=True)
    render_spec(sp, out / "renders", progress=progress, workers=workers, announce=console.say)
    t_render = time.perf_counter() - t0
    cells = cells_of(open_dataset(out / "renders"))
    todo = [(c, d) for c in cells for d in DETECTORS[c.kind]]
    done = out / "measured"
    done.mkdir(exist_ok=True)
    rows = []
    for cell, det in console.track(todo, desc="calibrate", unit="cell", enabled=progress):
        f = done / f"{cell.name}__{det}.json"
        if f.exists():
            row = read_json(f)
            if row.get("spec_identity") == sp.identity_sha256 and row.get("method_asked") == method:
                rows.append(row)
                continue
        row = measure_cell(cell, det, method) | {"spec_identity": sp.identity_sha256, "method_asked": method}
        write_json(f, row)
        rows.append(row)
    t_total = time.perf_counter() - t0
    cam = sp.camera
    header = {"spec": sp.name, "slots": max(g.count for g in sp.groups), "n_images": sp.n_images, "method": method,
              "camera": f"camera {sp.camera_ref} ({cam.width_px}×{cam.height_px} px, f {cam.focal_length_mm:g} mm, "
                        f"f/{cam.f_number:g})",
              "command": command or f"edgetruth study pattern --spec {spec} -o {out}"}
    write_json(out / "results.json", {"spec": sp.name, "spec_identity": sp.identity_sha256, "method": method,
                                      "seconds": {"render": t_render, "total": t_total}, "rows": rows})
    return write_report(rows, out, header)
