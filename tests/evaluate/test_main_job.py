"""`edgetruth run`: job selection, input errors, and (slow) the whole quick chain end to end."""
from __future__ import annotations

import pytest

from edgetruth.cli import main


def test_select_jobs_spreads_the_limit_over_each_group():
    from edgetruth.evaluate.main_job import select_jobs
    from edgetruth.render.dataset.spec import load_spec

    spec = load_spec("study")
    sel = select_jobs(spec, 2, "target")
    assert len(sel) == 14  # 2 per cell, 7 cells
    cells = [g for g in spec.groups if g.paired]
    picked = [{i - g.first_index for i in sel if g.first_index <= i < g.first_index + g.count} for g in cells]
    assert all(p == picked[0] for p in picked)  # the same pose slots in every cell: the pairs survive
    by_group = {}
    for j in spec.jobs:
        if j.index in sel:
            by_group.setdefault(j.group, []).append(j.distance_cm)
    assert all(min(v) < 100 and max(v) > 250 for v in by_group.values())
    assert select_jobs(spec, None, "target") == [j.index for j in spec.jobs]


def test_render_reuse_counts_one_render_per_pose_slot_and_radiance_unit():
    """study: 50 slots x 7 cells = 350 images; G2-G4 reuse G1's render, T2-T4 need their own: 200."""
    from edgetruth.evaluate.main_job import radiance_renders, render_reuse_line, select_jobs
    from edgetruth.render.dataset.spec import load_spec

    spec = load_spec("study")
    targets = select_jobs(spec, None, "target")
    assert (len(targets), radiance_renders(spec, targets)) == (350, 200)
    assert radiance_renders(spec, select_jobs(spec, 2, "target")) == 2 * 4  # --limit keeps the pairs
    line = render_reuse_line([(spec, targets)], {"n_rendered": 350, "reused": 150, "render_s": 400.0})
    assert line.startswith("350 images from 200 radiance renders (57 %") and "~300 s of rendering saved" in line


def test_bad_limit_is_a_one_line_input_error(capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main(["run", "--limit", "0", "-o", str(tmp_path)])
    assert info.value.code == 2 and "--limit" in capsys.readouterr().err
    assert main(["run", "--methods", "nope", "-o", str(tmp_path)]) == 2


@pytest.mark.slow
def test_quick_run_end_to_end(tmp_path, fast_variant):
    """Render quick and thresholds_quick (1 image per cell + 15 boards), calibrate the camera and its
    thresholds, locate, score every point, report (~40 s, llvm)."""
    from edgetruth.evaluate.main_job import select_jobs
    from edgetruth.render.dataset.spec import load_spec

    out = tmp_path / "run"
    assert main(["run", "--limit", "1", "--skip-synthetic", "--no-progress", "-o", str(out)]) == 0
    text = (out / "report.md").read_text()
    assert "Table 13" in text and "Claim-by-claim" in text and "INCONCLUSIVE" in text
    assert (out / "figures" / "fig9_boxplot.png").is_file()
    import csv
    rows = list(csv.DictReader(open(out / "ranging_rows.csv")))
    ok = [r for r in rows if r["method"] == "dynamic_erf_4p" and r["status"] == "ok"]
    assert len(ok) == len(select_jobs(load_spec("quick"), 1, "target"))  # one per cell
    assert all(float(r["rel_error_pct"]) < 2.0 for r in ok)
    # thresholds calibrated for the camera on renders of their own seeds, run next to the shipped ones
    import json
    import re

    thr = json.loads((out / "thresholds_camera.json").read_text())
    assert thr["provenance"]["data"]["specs"] == ["thresholds_quick"]
    assert any(r["method"] == "dynamic_erf_4p_camera" and r["status"] == "ok" for r in rows)
    assert "Table E1" in text and "(camera τ)" in text and "render reuse" in text
    assert "## Window shares: this run beside the full study" in text  # the quick run against the full study
    from edgetruth.evaluate.points.scores import read_points

    pts = read_points(out / "render_points.npz")
    assert len(pts.images) == len(ok) and "dynamic_erf_4p_camera" in pts.windows
    for link in re.findall(r"\]\(([^)]+)\)", text):  # every link of the report resolves
        assert (out / link).exists(), link


def test_kernel_warmup_runs_in_the_background_and_skips_unknown_methods(tiny_dataset):
    """The run starts the kernels' compilation beside its renders (a fresh clone has no numba cache);
    a method this process cannot run (a plug-in's) is skipped, never an error; a rendered image fed to it
    runs the ranging task there (bad input to it is skipped too: the warm-up only saves time)."""
    from edgetruth.evaluate.main_job import KernelWarmup, warm_kernels, warm_on_render
    from edgetruth.render.dataset.reader import open_dataset

    data = tiny_dataset[1]
    warm_kernels(["canny_pixel", "no_such_method"])  # in-process: returns
    name = next(s.name for s in open_dataset(data).targets())
    warm_on_render(data, name, ["canny_pixel", "dynamic_erf_4p"])  # in-process: returns
    warmup = KernelWarmup(["canny_pixel", "no_such_method"])
    assert warmup.proc is not None
    warmup.feed(data, name)
    warmup.feed(data, "no_such_image")
    assert warmup.finish() >= 0.0 and warmup.proc.returncode == 0


def test_first_target_skips_checkerboards():
    from edgetruth.evaluate.main_job import first_target, select_jobs
    from edgetruth.render.dataset.spec import load_spec

    spec = load_spec("quick")
    only = select_jobs(spec, None, "checkerboard") + select_jobs(spec, 1, "target")
    name = first_target(spec, sorted(only))
    assert name is not None and spec.jobs[[j.name for j in spec.jobs].index(name)].kind == "target"
    assert first_target(spec, select_jobs(spec, None, "checkerboard")) is None


def test_synthetic_study_beside_the_ranging_reports_its_path_or_its_failure(tmp_path):
    """The main job's synthetic study runs in a worker while this process goes on; result() waits for its
    report, or returns the failure as one line (the ranging results are kept either way)."""
    from edgetruth.evaluate.main_job import SyntheticBeside

    ok = SyntheticBeside(tmp_path / "syn", ["canny_pixel", "dynamic_erf_4p"], images_per_scenario=2)
    bad = SyntheticBeside(tmp_path / "bad", ["no_such_method"], images_per_scenario=2)
    path, err = ok.result()
    assert err is None and path == tmp_path / "syn" / "report.md" and path.is_file()
    assert SyntheticBeside.TIMING_NOTE in path.read_text() and "640×512 mosaic" in path.read_text()
    path, err = bad.result()
    assert path is None and "no_such_method" in err
    assert ok.seconds > 0 and bad.seconds > 0
