"""The main job and the evaluation of rendered datasets, as functions (the CLI's ``run`` and ``evaluate``).

``run_main_job``: render (specs) -> calibrate (Zhang) -> undistort -> find targets -> every
method -> ranging statistics -> ``report.md``, plus the synthetic study's quick preset linked
from the report.  ``evaluate_datasets``: the same evaluation of datasets a user rendered
with their own specs, with a calibration from a ``calibration.json`` or from checkerboard
renders.

Run directories (``run.json``): ``edgetruth.evaluate.run_dir``.
"""
from __future__ import annotations

import atexit
import os
import subprocess
import sys
import threading
import time
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from edgetruth import console, locate
from edgetruth.backends import PoolBackend, default_workers, numba_threads, worker_threads
from edgetruth.errors import InputError
from edgetruth.evaluate import method_order as mo, threshold_calibration as tcal
from edgetruth.evaluate.calibration import Calibration, calibrate_dataset
from edgetruth.evaluate.points import report as points_report, scores as point_scores
from edgetruth.evaluate.points.scores import score_image
from edgetruth.evaluate.ranging.images import UNDISTORT_LINES, check_undistort, range_image, run_ranging
from edgetruth.evaluate.ranging.report import write_report
from edgetruth.evaluate.ranging.size import fit_line_robust
from edgetruth.evaluate.run_dir import prepare_run_dir, utc_stamp
from edgetruth.evaluate.threshold_calibration import check_disjoint
from edgetruth.fileio import read_json, write_json
from edgetruth.locate.plugins import init_worker, worker_payload
from edgetruth.render.dataset.driver import RenderPool, check_variant_name, render_spec
from edgetruth.render.dataset.reader import open_dataset
from edgetruth.render.dataset.spec import load_spec
from edgetruth.render.synthetic.scenarios import synthetic_image
from edgetruth.resources import default_runs_dir


STUDIES = {
    "quick": {"calibration": "quick", "targets": ["quick"], "thresholds": "thresholds_quick"},
    "full": {"calibration": "calibration", "targets": ["study"], "thresholds": "thresholds"},
}


def warm_kernels(methods=None, thresholds=None) -> None:
    """Call every method once on a small analytic image: numba compiles the kernels it has not cached
    yet and writes them to its on-disk cache (``edgetruth.jit``).  A method that fails here
    (a plug-in this process does not know) is skipped: the warm-up only saves time."""
    options = mo.study_options(thresholds)
    s = synthetic_image("ideal", 0, split="unit")
    cand = locate.candidates(s.image)
    for m in methods or mo.ordered(None):
        try:
            mid, kw = mo.resolve(m, options)
            locate.refine(s.image, cand, mid, **kw)
        except Exception:  # noqa: BLE001 -- the stage that runs the method reports its failure
            continue


    t = np.linspace(-20.0, 20.0, 200)  # > 128 points: the pairwise sum's halving path too
    fit_line_robust(10.0 + 0.01 * t, 5.0 + t)


def warm_on_render(dataset, name: str, methods=None, thresholds=None) -> None:
    """The ranging task (``range_image``: undistortion, target finding, every method, sizes, per-point scores
    and bounds) on one rendered target image, with the camera's true intrinsics standing in for the
    calibration: numba compiles every kernel the ranging workers call, with the argument types they pass
    (``warm_kernels``' analytic image reaches most, not those of a camera's ESF tables)."""
    cam = open_dataset(dataset)[name].truth["camera"]
    cal = Calibration(K=np.asarray(cam["K"], float), dist=np.asarray(cam["dist_coeffs_opencv"], float), rms_px=float("nan"), n_views=0,
                      image_size=(int(cam["width_px"]), int(cam["height_px"])))
    range_image(str(dataset), name, cal, list(methods or mo.ordered(None)), False, mo.study_options(thresholds),
                score=score_image)


def _warm_main(argv) -> None:
    """The warm-up process: ``warm_kernels``, then ``warm_on_render`` for each "dataset<TAB>name" line on stdin."""
    thresholds, methods = argv[0] or None, argv[1:] or None
    warm_kernels(methods, thresholds)
    for line in sys.stdin:
        dataset, _, name = line.rstrip("\n").partition("\t")
        if name:
            try:
                warm_on_render(dataset, name, methods, thresholds)
            except Exception:  # noqa: BLE001 -- the warm-up only saves time; the ranging stage reports failures
                pass


class KernelWarmup:
    """``warm_kernels`` in a background process, started before the renders: on a fresh clone (no numba
    cache) the kernels' compilation (~45 s of one core, measured) then overlaps the rendering instead
    of running afterwards in the workers of the ranging and synthetic stages.  ``feed(dataset, name)``
    hands it a rendered target image to run the ranging task on (``warm_on_render``); ``finish()``
    closes its input and waits.  With a warm cache it only loads the kernels (a few seconds of one core
    beside the renders).  Processes that need a kernel the warm-up is compiling wait for it and load it
    from the cache (``edgetruth.jit``'s compile locks) rather than compile it again."""

    def __init__(self, methods=None, thresholds=None, threads: int | None = None):
        code = "import sys; from edgetruth.evaluate.main_job import _warm_main; _warm_main(sys.argv[1:])"
        env = dict(os.environ)
        mine = env.get("NUMBA_NUM_THREADS", "")
        if threads and not (mine.isdigit() and 0 < int(mine) <= threads):  # a smaller setting of the user's stays
            env["NUMBA_NUM_THREADS"] = str(threads)  # the ranging workers' count: on one, strict kernels compile
            # their serial copies (edgetruth.jit)
        try:
            self.proc = subprocess.Popen([sys.executable, "-c", code, str(thresholds or ""), *(methods or [])],
                                         stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                         stderr=subprocess.DEVNULL, text=True, env=env)
        except OSError:
            self.proc = None
            return
        proc = self.proc
        atexit.register(lambda: proc.poll() is None and proc.kill())  # a run that stops early leaves none behind

    def feed(self, dataset, name: str) -> None:
        if self.proc is not None and self.proc.poll() is None:
            try:
                self.proc.stdin.write(f"{dataset}\t{name}\n")
                self.proc.stdin.flush()
            except OSError:  # it has gone: the stages compile what they need themselves
                pass

    def finish(self) -> float:
        """Close its input and wait for it; returns the seconds waited."""
        t = time.perf_counter()
        if self.proc is not None:
            try:
                self.proc.stdin.close()
            except OSError:
                pass
            self.proc.wait()
        return time.perf_counter() - t


def _synthetic_task(out_dir: str, methods, thresholds, note: str, images_per_scenario: int | None) -> str:
    from edgetruth.evaluate.synthetic.study import run_synthetic_study  # lazy: study loads numba

    return str(run_synthetic_study(out_dir, preset="quick", methods=methods, progress=False, thresholds=thresholds,
                                   workers=1, timing_note=note, images_per_scenario=images_per_scenario))


class SyntheticBeside:
    """The synthetic study's quick preset in a worker process, started when the renders are done: it runs
    beside calibration, thresholds and ranging (in this process it left one of two cores idle for ~20 s).
    The worker learns this process's plug-in methods as any pool worker does; a thread here only waits
    for it.  ``result()`` waits and returns (report path or None, error line or None)."""

    TIMING_NOTE = ("Inside `edgetruth run` this study ran beside the ranging stage, on loaded cores: read its "
                   "ratios, not its absolute points/s (`make bench` measures those on quiet cores).")

    def __init__(self, out_dir: Path, methods=None, thresholds=None, images_per_scenario: int | None = None,
                 threads: int = 1):
        self.t0 = time.perf_counter()
        self.seconds = None
        self._out: dict = {}
        backend = PoolBackend(1, init_worker, worker_payload(methods), threads=threads)  # sharing the cores
        task = (str(out_dir), methods, str(thresholds) if thresholds else None, self.TIMING_NOTE, images_per_scenario)

        def wait():
            try:
                with backend:
                    for path in backend.map_unordered(_synthetic_task, [task]):
                        self._out["path"] = Path(path)
            except Exception as exc:  # noqa: BLE001 -- reported by result(); the ranging results stay
                self._out["error"] = f"{type(exc).__name__}: {exc}"
            self.seconds = time.perf_counter() - self.t0

        self._thread = threading.Thread(target=wait, name="edgetruth-synthetic", daemon=True)
        self._thread.start()

    def result(self) -> tuple[Path | None, str | None]:
        self._thread.join()
        if "path" in self._out:
            return self._out["path"], None
        return None, self._out.get("error", "no report")


def first_target(spec, only) -> str | None:
    """The name of the first target image among the jobs ``only`` of ``spec`` (None: none)."""
    return next((spec.jobs[i].name for i in only if spec.jobs[i].kind == "target"), None)


def select_jobs(spec, limit: int | None, kind: str) -> list[int]:
    """Indices of the jobs of ``kind`` to render: all, or ``limit`` per group spread over distance."""
    out = []
    for g in spec.groups:
        if g.kind != kind:
            continue
        order = sorted(range(g.count), key=lambda k: g.distances_cm[k])
        if limit is None or limit >= g.count:
            pick = range(g.count)
        else:
            pick = sorted({order[int(round(k))] for k in
                           ([0.0] if limit == 1 else [i * (g.count - 1) / (limit - 1) for i in range(limit)])})
        out += [g.first_index + k for k in pick]
    return sorted(out)


def radiance_renders(spec, only) -> int:
    """How many radiance renders the images ``only`` of ``spec`` need: one per (pose slot, radiance
    unit) of a paired design -- the cells that differ in light or sensor share it -- one per other image."""
    keys = set()
    for i in only:
        j = spec.jobs[i]
        keys.add(("unit", j.slot, j.radiance_unit) if j.slot is not None else ("image", i))
    return len(keys)


def render_reuse_line(target_sets, timing: dict) -> str:
    """What the paired design's radiance reuse saves in this run's renders (and, when they were
    rendered now, the time inside ``mi.render`` it saved)."""
    n = sum(len(only) for _, only in target_sets)
    r = sum(radiance_renders(spec, only) for spec, only in target_sets)
    if not n:
        return ""
    line = f"{n} images from {r} radiance renders ({100 * r / n:.0f} % of the images; " + ", ".join(
        f"{spec.name} {len(only)} from {radiance_renders(spec, only)}" for spec, only in target_sets) + ")"
    done, reused = timing.get("n_rendered", 0), timing.get("reused", 0)
    if done > reused:
        per = timing.get("render_s", 0.0) / (done - reused)  # inside mi.render per radiance render, all workers
        line += f"; rendered now: {done} images, {reused} reused a render, ~{reused * per:.0f} s of rendering saved"
    return line


def evaluate_datasets(datasets: list[Path], calibration, out: Path, methods=None, thresholds=None,
                      progress: bool = True, names: dict | None = None, backend: str = "local",
                      workers: int | None = 1, address: str | None = None, header: dict | None = None,
                      synthetic_report: Path | None = None, title: str = "evaluation report",
                      camera_thresholds=None, windows_beside_full: bool = False, undistort: str = "image") -> Path:
    """Range every target image of ``datasets`` with every method, score every method's points
    against the exact outline, and write ``report.md`` into ``out``.  ``camera_thresholds``: a file
    of thresholds calibrated for the camera (``calibrate-thresholds --dataset``); the dynamic methods
    then also run with them (labels ``*_camera``).  ``windows_beside_full``: the report sets the dynamic
    methods' window shares beside the full study's (the quick run's report)."""
    options = mo.study_options(thresholds, camera_thresholds)
    tau = mo.thresholds_in_use(thresholds)
    samples = [(f"{d}/{s.name}", s.truth) for d in datasets for s in open_dataset(d).targets()
               if names is None or str(d) not in names or s.name in set(names[str(d)])]
    for f in (thresholds, camera_thresholds):
        check_disjoint(f, samples)
    if camera_thresholds is not None:
        methods = mo.ordered(list(methods or locate.METHODS) + [
            v for v in mo.variant_labels(options) if options[v]["method"] in (methods or locate.METHODS)])
    result = run_ranging(datasets, calibration, out, methods=methods, progress=progress, names=names,
                         options=options, backend=backend, workers=workers, address=address, undistort=undistort,
                         score=point_scores.score_image)
    # the per-point study on the same candidates, scored in the ranging's workers (one read of each image)
    points = point_scores.table_from_scores(result["point_images"], result["point_scores"], result["methods"])
    point_scores.write_points(Path(out) / point_scores.POINTS_FILE, points)
    head = dict(header or {})
    head.setdefault("target images", len({(r.get("spec"), r["image"]) for r in result["rows"]}))
    outside = {}  # images the ranging does not size (an own scene of several outlines, a shape it does not model)
    for r in result["rows"]:
        if str(r.get("status", "")).startswith("not ranged: "):
            outside.setdefault(r["status"][len("not ranged: "):], set()).add((r.get("spec"), r["image"]))
    if outside:
        head["not ranged"] = "; ".join(f"{len(v)} image(s): {why}" for why, v in outside.items()) + \
            " (their rows count as failed in the ranging tables; the per-point tables score them)"
    head.setdefault("methods", len(result["methods"]))
    head.setdefault("undistortion", UNDISTORT_LINES[undistort])
    head["entropy thresholds"] = f"2P {tuple(tau['2p'])}, 4P {tuple(tau['4p'])} ({tau['label']})"
    if camera_thresholds is not None:
        ct = mo.thresholds_in_use(camera_thresholds)
        head["entropy thresholds for this camera (camera τ)"] = (
            f"2P {tuple(ct['2p'])}, 4P {tuple(ct['4p'])} (from {Path(camera_thresholds).name}: calibrated on renders "
            "disjoint from these, `edgetruth calibrate-thresholds --dataset`)")
    if callable(synthetic_report):  # the main job's synthetic study, running beside the ranging: wait for it now
        synthetic_report, more = synthetic_report()
        head.update(more)
    section = points_report.report_section(points, [m for m in result["methods"] if m in points.errors], Path(out)) \
        if len(points.image) else []
    return write_report(out, result["rows"], result["methods"], calibration, result["examples"], head,
                        str(synthetic_report) if synthetic_report else None, title=title, points_section=section,
                        windows_beside_full=windows_beside_full)


def run_main_job(study: str = "quick", out: str | Path | None = None, limit: int | None = None,
                 calib_limit: int | None = None, methods=None, variant: str | None = None,
                 skip_synthetic: bool = False, progress: bool = True, thresholds=None,
                 workers: int | None = None, camera_thresholds=None, undistort: str = "image") -> tuple[Path, int]:
    """The main job in one call, as ``edgetruth run``: render, calibrate, locate, range, score, report.

    Parameters
    ----------
    study : str, optional
        ``"quick"`` (default; ``make run``) or ``"full"`` (the reference study of docs/results/ranging_full).
    out : str or pathlib.Path, optional
        The run folder (default ``runs/<UTC stamp>``); an earlier run's folder resumes it.
    limit : int, optional
        Render and evaluate at most this many target images per group.
    calib_limit : int, optional
        At most this many calibration boards (>= 4).
    methods : list of str, optional
        Method ids (with ``:key=value`` options); default every registered method.
    variant : str, optional
        Mitsuba's variant (default: the fastest that runs here).
    skip_synthetic : bool, optional
        Leave out the synthetic study's quick preset.
    progress : bool, optional
        Progress bars (on a terminal).
    thresholds : str or pathlib.Path, optional
        An entropy-thresholds file for the dynamic methods (default: the shipped one).
    workers : int, optional
        Render and evaluation worker processes (default: one per core).
    camera_thresholds : str or pathlib.Path, optional
        Thresholds calibrated for the camera; default: calibrated by the run on its threshold renders.
    undistort : str, optional
        ``"image"`` (default: remap the image, every method refines it) or ``"points"`` (refine the raw
        image and undistort the points).

    Returns
    -------
    tuple
        (path of ``report.md``, exit code: 0, or 1 when a check of the run failed).
    """
    if study not in STUDIES:
        raise InputError(f"--study {study!r}: choose one of {', '.join(STUDIES)}")
    if limit is not None and limit < 1:
        raise InputError(f"--limit {limit}: must be >= 1")
    if calib_limit is not None and calib_limit < 4:
        raise InputError(f"--calib-limit {calib_limit}: Zhang's method needs >= 4 boards here")
    mo.thresholds_in_use(thresholds)  # a bad --thresholds file fails now, not after the renders
    if camera_thresholds is not None:
        mo.thresholds_in_use(camera_thresholds)
    check_variant_name(variant)
    check_undistort(undistort)
    plan = STUDIES[study]
    cal_spec = load_spec(plan["calibration"])
    target_specs = [load_spec(n) for n in plan["targets"]]
    thr_spec = load_spec(plan["thresholds"]) if camera_thresholds is None else None
    out = prepare_run_dir(out or default_runs_dir() / utc_stamp(), "run",
                          {"study": study, "limit": limit, "calib_limit": calib_limit, "methods": methods,
                           "thresholds": str(thresholds) if thresholds else None,
                           "camera_thresholds": str(camera_thresholds) if camera_thresholds else None,
                           "undistort": undistort})
    workers = default_workers() if workers is None else workers
    t0 = time.perf_counter()
    timing: dict = {}
    console.say(f"run: study {study!r} -> {out}")
    # numba threads: the ranging's workers get worker_threads(workers) each; the synthetic study beside them
    # a share of its own, this process the rest (on 2 cores: one each, so strict kernels run their serial
    # copies everywhere and compile once: edgetruth.jit)
    syn_threads = worker_threads(workers + 1)
    main_threads = max(1, default_workers() - (0 if skip_synthetic else syn_threads))
    ranging_threads = worker_threads(workers) if workers > 1 else main_threads  # workers = 1: in this process
    warmup = KernelWarmup(methods, thresholds, threads=ranging_threads)  # compiles beside the renders

    # 1. render
    render_dir = out / "render"
    t = time.perf_counter()
    variants: list[str] = []
    cal_only = select_jobs(cal_spec, None, "checkerboard")
    if calib_limit is not None:
        cal_only = cal_only[:calib_limit]
    target_sets = []
    for spec in target_specs:
        only = select_jobs(spec, limit, "target")
        if spec.name == cal_spec.name:
            only = sorted(set(only) | set(cal_only))
        target_sets.append((spec, only))
    if cal_spec.name not in plan["targets"]:
        target_sets.insert(0, (cal_spec, cal_only))
    if thr_spec is not None:  # threshold calibration renders: a spec (and seeds) of their own
        target_sets.insert(0, (thr_spec, select_jobs(thr_spec, limit, "target")))
    stats: dict = {}
    fed = False
    # one worker process per core (one Dr.Jit thread each): a render's single-threaded parts (the coverage,
    # ground truth, sensor, encoding, hashing) overlap the other worker's render instead of leaving a core
    # idle; the files are the same bytes as in-process (tests/cli/test_backends.py).  One pool serves every
    # spec: its workers start and warm up once.
    with RenderPool([s for s, _ in target_sets], workers) if workers > 1 else nullcontext() as pool:
        for spec, only in target_sets:
            render_spec(spec, render_dir / spec.name, variant=variant, progress=progress, only=only, timings=stats,
                        announce=lambda s: (variants.append(s), console.say(s)), workers=workers, pool=pool)
            if not fed and first_target(spec, only):  # the ranging task on one image: the ranging's kernels
                warmup.feed(render_dir / spec.name, first_target(spec, only))
                fed = True
    timing["render_s"] = time.perf_counter() - t
    reuse_line = render_reuse_line(target_sets, stats)
    if reuse_line:
        console.say("render: " + reuse_line)

    # 2. synthetic study (quick preset), linked from the report: in a worker from here on, beside 3 and 4
    synthetic = None if skip_synthetic else SyntheticBeside(out / "synthetic", methods, thresholds, threads=syn_threads)
    with numba_threads(main_threads):  # beside the synthetic study's worker: the cores' rest
        # 3. calibrate
        t = time.perf_counter()
        cal_names = [cal_spec.jobs[i].name for i in cal_only]
        cal = calibrate_dataset(render_dir / cal_spec.name, names=cal_names, progress=progress)
        write_json(out / "calibration.json", cal.to_dict())
        e = cal.errors()
        console.say(f"calibrate: {cal.n_views} boards, RMS {cal.rms_px:.3f} px, fx {cal.fx:.2f} px "
                    f"({e.get('fx_rel_pct', float('nan')):+.3f} % vs truth), principal point error "
                    f"({e.get('cx_px', float('nan')):+.2f}, {e.get('cy_px', float('nan')):+.2f}) px")
        timing["calibrate_s"] = time.perf_counter() - t

        # the kernels are cached from here on: the stages below (and their workers) load them
        timing["kernel_wait_s"] = warmup.finish()

        # 3b. entropy thresholds for this camera, from the disjoint threshold renders' per-point truth
        if thr_spec is not None:
            t = time.perf_counter()
            thr_names = [thr_spec.jobs[i].name for i in select_jobs(thr_spec, limit, "target")]
            record = tcal.calibrate_renders([render_dir / thr_spec.name], names=thr_names)
            record["provenance"]["command"] = (f"edgetruth calibrate-thresholds --dataset render/{thr_spec.name} "
                                               "(inside edgetruth run)")
            camera_thresholds = out / "thresholds_camera.json"
            tcal.write(record, camera_thresholds)
            data = record["provenance"]["data"]
            console.say("thresholds for the camera: " + "; ".join(
                f"{m} tau {tuple(round(v, 2) for v in r['tau'])} RMSE {r['rmse_px']:.4f} px"
                for m, r in record["models"].items())
                + f" ({data['on_edge_points']} points of {len(data['images'])} {thr_spec.name} images)")
            timing["thresholds_s"] = time.perf_counter() - t

        # 4. locate + evaluate + report
        t = time.perf_counter()
        datasets = [render_dir / s.name for s, _ in target_sets if s.name in plan["targets"]]
        names = {str(render_dir / s.name): [s.jobs[i].name for i in only]
                 for s, only in target_sets if s.name in plan["targets"]}
        header = {"study": study, "UTC": utc_stamp(), "specs": ", ".join(s.name for s, _ in target_sets),
                  "Mitsuba": "; ".join(variants) or "renders reused (already complete)",
                  "undistortion": UNDISTORT_LINES[undistort]}
        if reuse_line:
            header["render reuse"] = reuse_line
        header["timings so far (s)"] = ", ".join(f"{k} {v:.1f}" for k, v in timing.items())
        outcome: dict = {"failed": False}

        def wait_synthetic():  # called before the report is written: the ranging ran beside the synthetic study
            if synthetic is None:
                return None, {}
            path, err = synthetic.result()
            timing["synthetic_s"] = synthetic.seconds
            if err is not None:
                outcome["failed"] = True
                console.say(f"run: synthetic study failed: {err}")
                return None, {"synthetic study": "FAILED (see the console)"}
            return path, {}

        report = evaluate_datasets(datasets, cal, out, methods=methods, thresholds=thresholds, progress=progress,
                                   names=names, workers=workers, header=header, synthetic_report=wait_synthetic,
                                   title=f"run report (study {study})", camera_thresholds=camera_thresholds,
                                   windows_beside_full=study == "quick", undistort=undistort)
        timing["ranging_s"] = time.perf_counter() - t
        console.say(f"run: report {report} ({time.perf_counter() - t0:.1f} s in all: "
                    + ", ".join(f"{k} {v:.1f}" for k, v in timing.items()) + ")")
        return report, 1 if outcome["failed"] else 0
