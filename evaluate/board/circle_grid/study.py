"""The board study on a circle grid (docs/board.md, "Circle grids"): steps as the board study's
(``evaluate.board.study``), on circles.

1. the photos (``inputs``, a ``CircleBoard``), read as stored;
2. the grid on every photo (``rows.setup_grids``: photos without it skipped with why), the blob calibration, the
   predicted outlines and the Canny candidates, once, shared by every method;
3. the reference row (OpenCV's blob centroids) and one row per method (its corrected centres), each calibrated
   with leave-one-image-out (``rows``);
4. per-row figures (``summary``), paired tests (``measure.compare``), files (``report``).

Nothing is written until every step has run.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

from edgetruth import console
from edgetruth.evaluate import method_order as mo
from edgetruth.evaluate.board.circle_grid import rows as R
from edgetruth.evaluate.board.circle_grid.summary import (FAMILIES, FAMILY_LABELS, circle_summary,
                                                          per_circle_rows, per_photo)
from edgetruth.evaluate.board.inputs import BoardInputs, load_photos_scaled
from edgetruth.evaluate.board.measure.compare import compare_all


@dataclass
class CircleRun:
    """Everything one circle-grid study computed (``compute_circle_study``), before anything is written.

    Attributes
    ----------
    inp : BoardInputs
        The checked inputs (``inp.circles`` the board).
    setup : rows.GridSetup
        The grids found and what every row shares.
    rows : list of rows.CircleRow
        One per method, then the reference row.
    summaries : list of dict
        ``summary.circle_summary`` of each row.
    comparisons : list of dict
        The paired tests (``measure.compare.compare_all``) of ``summary.FAMILIES``.
    per_circle : list of dict
        per_circle.csv's lines.
    elapsed_s : float
        The study's time.
    reference_label : str
        The reference row's label.
    """

    inp: BoardInputs
    setup: R.GridSetup
    rows: list
    summaries: list
    comparisons: list
    per_circle: list
    elapsed_s: float
    reference_label: str = R.REFERENCE_LABEL


def compute_circle_study(inp: BoardInputs, methods: list[str], options: dict, channel: str = "luma",
                         progress: bool = True) -> CircleRun:
    """Steps 1-4 of the study (module docstring) on checked inputs; nothing is written.

    Parameters
    ----------
    inp : BoardInputs
        Photos and a circle grid (``inp.circles``), from ``inputs.resolve_inputs``.
    methods : list of str
        The method labels, one row each.
    options : dict
        Per-method options (``method_order.study_options``).
    channel : str
        How colour photos are read as gray (``image_io.read_gray``).
    progress : bool
        Show progress on the console.

    Returns
    -------
    CircleRun
        Every row, figure and test.
    """
    t0 = time.perf_counter()
    images, scales = load_photos_scaled(inp.photos, channel)
    setup = R.setup_grids(inp.names, images, scales, inp.circles, progress)
    rows = []
    for label in console.track(methods, desc="methods", unit="method", enabled=progress):
        method, kw = mo.resolve(label, options)
        rows.append(R.method_row(label, method, kw, setup))
    rows.append(R.reference_row(setup))
    for r in console.track(rows, desc="calibration", unit="row", enabled=progress):
        R.calibrate_row(r, setup)
    summaries = [circle_summary(r, setup.blobs) for r in rows]
    comparisons = [{**c, "label": FAMILY_LABELS[c["family"]]}
                   for c in compare_all(rows, families=FAMILIES, per_photo=per_photo)]
    return CircleRun(inp, setup, rows, summaries, comparisons, per_circle_rows(rows, setup.names),
                     time.perf_counter() - t0)


def write_circle_run(run: CircleRun, out, channel: str, methods: list[str], options: dict, thresholds,
                     title: str | None = None):
    """The study's files (``report.write_circle_outputs``) of ``run`` into the existing directory ``out``.

    Parameters
    ----------
    run : CircleRun
        What ``compute_circle_study`` computed.
    out : pathlib.Path
        The run directory (``run_dir.prepare_run_dir``).
    channel : str
        How the photos were read (for the header).
    methods : list of str
        The method labels (for the header).
    options : dict
        Per-method options (for the header).
    thresholds : str or None
        The ``--thresholds`` file, None for the shipped ones (for the header).
    title : str or None
        The report's title (default: the set's name or the photo count).

    Returns
    -------
    pathlib.Path
        report.md.
    """
    from edgetruth.evaluate.board.circle_grid.report import header_lines, write_circle_outputs  # lazy: matplotlib

    inp = run.inp
    title = title or f"Board study (circle grid) — {inp.set_name or f'{len(inp.photos)} photos'}"
    return write_circle_outputs(out, run, title, header_lines(run, channel, methods, options, thresholds))
