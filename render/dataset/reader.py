"""Reading a rendered dataset back: images with their ground truth, and checking it against its manifest.

    from edgetruth.render import open_dataset
    ds = open_dataset("runs/render/quick")
    for s in ds:                      # complete images, in index order
        s.name, s.kind, s.group       # "0000_T1", "target" | "checkerboard" | "squares", "T1"
        s.image                       # uint16 (H, W) sensor image, raw DN (read on first use)
        s.radiance                    # float32 (H, W) linear radiance, W m^-2 sr^-1 (EXR)
        s.truth                       # the ground-truth JSON (docs/formats.md)
    ds["0003_T4"], ds[0], len(ds), ds.targets(), ds.checkerboards(), ds.square_boards()

The layout: per image ``NAME.exr``, ``NAME.png`` and ``NAME.json``; ``manifest.json``
lists every image with the SHA-256 of each file, and while a render runs (or after it was
killed) ``journal.jsonl`` holds the images finished since (``edgetruth.render.dataset.journal``).
Both forms are read: the journal's entries are merged into the manifest's.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from edgetruth.errors import InputError
from edgetruth.fileio import is_temporary, read_json, sha256_file
from edgetruth.render.dataset.journal import JOURNAL, MANIFEST, JournalScan, ManifestReader, iter_journal

__all__ = ["MANIFEST", "JOURNAL", "Dataset", "Sample", "check_dataset", "load_image", "load_manifest", "open_dataset"]


def load_manifest(d: str | Path, scan: JournalScan | None = None) -> dict:
    """The manifest of dataset ``d`` with the journal's entries merged in (the latest entry of an
    image wins), images in index order; one InputError if it is not a dataset or is damaged.
    ``scan`` (a ``JournalScan``) receives what reading the journal found."""
    d = Path(d)
    if not d.exists():
        raise InputError(f"{d}: no such directory; pass the -o directory of `edgetruth render`")
    if not d.is_dir():
        raise InputError(f"{d}: not a directory; pass the -o directory of `edgetruth render`")
    mpath = d / MANIFEST
    if not mpath.is_file():
        raise InputError(f"{d}: no {MANIFEST}, so not an edgetruth dataset; render one with "
                         f"`edgetruth render SPEC -o {d}`")
    reader = ManifestReader(mpath)
    m = dict(reader.header)
    images = dict(reader)
    scan = scan if scan is not None else JournalScan()
    if (d / JOURNAL).is_file():
        for _, name, entry in iter_journal(d / JOURNAL, m["n_images"], scan):
            images.pop(name, None)
            images[name] = entry
        images = dict(sorted(images.items(), key=lambda kv: kv[1]["index"]))
    m["images"] = images
    return m


@dataclass
class Sample:
    """One rendered image of a dataset with its exact ground truth; pixels are read when first asked for.

    Attributes
    ----------
    dataset : Dataset
        The dataset it belongs to.
    name : str
        The image's name (``"0015_G1_T1"``): its files are ``NAME.png``, ``NAME.exr``, ``NAME.json``.
    index : int
        Its index in the spec (``spec.jobs[index]``).
    kind : str
        ``"target"``, ``"checkerboard"`` or ``"squares"``.
    group : str
        The spec group (or design cell) it belongs to.
    truth : dict
        The ground-truth JSON (docs/formats.md).
    outline : OutlineEdge or SceneOutline or None
        The exact distorted truth of every visible edge (target images): ``signed_distance(x, y)`` in px,
        > 0 on the bright board.
    optical_outline : OpticalOutline or None
        The edge the optics form, beside the geometric outline.
    image : numpy.ndarray
        The sensor image, uint16 (H, W), raw DN.
    radiance : numpy.ndarray
        The linear radiance, float32 (H, W), W m^-2 sr^-1.
    """

    dataset: "Dataset" = field(repr=False)
    name: str
    index: int
    kind: str
    group: str
    _truth: dict | None = field(default=None, repr=False)

    def _file(self, key: str) -> Path:
        return self.dataset.path / self.dataset.manifest["images"][self.name]["files"][key]["path"]

    @property
    def truth(self) -> dict:
        """The ground-truth JSON (camera, pose, outline or corners, sensor, seeds; docs/formats.md)."""
        if self._truth is None:
            self._truth = read_json(self._file("json"))
        return self._truth

    @property
    def outline(self):
        """The exact distorted truth of every visible edge of a target image; None for a checkerboard.

        One outline (a preset T1-T4, or a scene of one shape with one outline): ``OutlineEdge``, shape 0's
        outline.  Several (shapes that cover one another, a ring's two edges): ``SceneOutline``
        (``edgetruth.render.scene.ground_truth``), the visible parts of every outline.  Both give
        ``signed_distance(x, y)`` in px (> 0 outside, on the bright board) and ``corner_distance(x, y)``;
        ``SceneOutline`` also ``edge_index`` / ``edge_shape`` (which outline / shape is nearest) and
        ``shape_at`` (which shape the point shows)."""
        from edgetruth.render.scene.ground_truth import image_outline

        return image_outline(self.truth) if self.kind == "target" else None

    @property
    def optical_outline(self):
        """The target's *optical* edge (``edgetruth.render.optics.optical_edge.OpticalOutline``): the outline
        moved along its normal by the displacement the camera model predicts (the JSON's
        ``outline.optical_edge``); ``signed_distance(x, y, level="centroid" | "median")`` in px, > 0
        on the bright board; ``geometric_signed_distance`` as ``outline``.  None for a checkerboard or a
        JSON without the block."""
        from edgetruth.render.optics.optical_edge import OpticalOutline

        if self.kind != "target" or "optical_edge" not in self.truth.get("outline", {}):
            return None
        return OpticalOutline.from_ground_truth(self.truth)

    @property
    def image(self) -> np.ndarray:
        """The sensor image, uint16 (H, W), raw DN."""
        from edgetruth.render.dataset.files import read_png16

        return read_png16(self._file("png"))

    @property
    def radiance(self) -> np.ndarray:
        """The linear radiance the sensor saw, float32 (H, W), W m^-2 sr^-1."""
        from edgetruth.render.dataset.files import read_exr

        return read_exr(self._file("exr"))


class Dataset:
    """A rendered dataset folder: ``len``, iteration and indexing over its complete images.

    ``ds[0]`` (index order), ``ds["0015_G1_T1"]`` (name), ``for s in ds``; ``targets()``,
    ``checkerboards()``, ``square_boards()`` select by kind.

    Parameters
    ----------
    path : str or pathlib.Path
        The ``-o`` folder of ``edgetruth render`` (or ``render_spec``).

    Attributes
    ----------
    path : pathlib.Path
        The folder.
    manifest : dict
        The manifest with the journal's entries merged in (``images``: name -> entry with file hashes).
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.manifest = load_manifest(self.path)
        entries = sorted(((n, e) for n, e in self.manifest["images"].items() if e.get("complete")),
                         key=lambda kv: kv[1]["index"])
        self._samples = [Sample(self, n, int(e["index"]), str(e.get("kind", "")), str(e.get("group", "")))
                         for n, e in entries]
        self._by_name = {s.name: s for s in self._samples}

    @property
    def spec_name(self) -> str:
        """The name of the spec the dataset was rendered from."""
        return str(self.manifest.get("spec", ""))

    @property
    def n_declared(self) -> int:
        """How many images the spec declares (``len`` counts the complete ones)."""
        return int(self.manifest["n_images"])

    def names(self) -> list[str]:
        """The complete images' names, in index order.

        Returns
        -------
        list of str
            E.g. ``["0000_calib", "0015_G1_T1", ...]``.
        """
        return [s.name for s in self._samples]

    def __len__(self) -> int:
        return len(self._samples)

    def __iter__(self):
        return iter(self._samples)

    def __getitem__(self, key: int | str) -> Sample:
        if isinstance(key, str):
            if key not in self._by_name:
                raise KeyError(f"{self.path}: no complete image named {key!r}")
            return self._by_name[key]
        return self._samples[key]

    def targets(self) -> list[Sample]:
        """The target images (``kind = "target"``), in index order.

        Returns
        -------
        list of Sample
            Each with its ``outline``.
        """
        return [s for s in self._samples if s.kind == "target"]

    def checkerboards(self) -> list[Sample]:
        """The checkerboard images (``kind = "checkerboard"``: calibration boards), in index order.

        Returns
        -------
        list of Sample
            Their truth holds the inner corners.
        """
        return [s for s in self._samples if s.kind == "checkerboard"]

    def square_boards(self) -> list[Sample]:
        """Images of boards of squares (``kind = "squares"``; their truth's ``squares`` block), in index order.

        Returns
        -------
        list of Sample
            The board images.
        """
        return [s for s in self._samples if s.kind == "squares"]

    def __repr__(self) -> str:
        return f"Dataset({str(self.path)!r}, spec={self.spec_name!r}, {len(self)}/{self.n_declared} images)"


def open_dataset(path: str | Path) -> Dataset:
    """Open a rendered dataset for reading (also while it renders, or after a killed run).

    Parameters
    ----------
    path : str or pathlib.Path
        The ``-o`` folder of ``edgetruth render``.

    Returns
    -------
    Dataset
        Its complete images, in index order, each a ``Sample``.

    Raises
    ------
    edgetruth.errors.InputError
        Not a folder, no ``manifest.json``, or a damaged record.

    Examples
    --------
    >>> ds = open_dataset("runs/quick")                      # doctest: +SKIP
    >>> s = ds["0015_G1_T1"]                                 # doctest: +SKIP
    >>> s.image, s.truth["true_distance_m"], s.outline       # doctest: +SKIP
    """
    """A rendered dataset (the ``-o`` directory of ``edgetruth render``)."""
    return Dataset(path)


def load_image(out_dir: str | Path, name: str) -> tuple[np.ndarray, dict]:
    """(sensor image uint16 (H, W), ground truth dict) of image ``name`` in a dataset directory."""
    s = open_dataset(out_dir)[name]
    return s.image, s.truth


def check_dataset(d: str | Path) -> tuple[list[str], dict]:
    """(problems, info) for dataset ``d``: one human-readable line per problem (missing or damaged
    file, temporary left by a killed run, unlisted file, images not yet rendered)."""
    d = Path(d)
    scan = JournalScan()
    m = load_manifest(d, scan)
    problems: list[str] = [scan.problem()] if scan.problem() else []
    if scan.spec_sha256 not in (None, m.get("spec_sha256")):
        problems.append(f"{JOURNAL}: written for another spec; delete it (its images are rendered again)")
    listed = {MANIFEST, JOURNAL}
    complete = 0
    for name, entry in m["images"].items():
        ok = bool(entry.get("complete"))
        if not ok:
            problems.append(f"incomplete: {name} (manifest entry not marked complete)")
        for f in entry["files"].values():
            rel = f["path"]
            listed.add(rel)
            p = d / rel
            if Path(rel).is_absolute() or ".." in Path(rel).parts:
                problems.append(f"bad path: {name}: {rel!r} is outside the dataset")
                ok = False
            elif not p.is_file():
                problems.append(f"missing: {rel}")
                ok = False
            elif sha256_file(p) != f["sha256"]:
                problems.append(f"hash mismatch: {rel} (file changed or damaged since it was rendered)")
                ok = False
        complete += ok
    for p in sorted(d.iterdir()):
        if is_temporary(p):
            problems.append(f"extra-temp: {p.name} (left by an interrupted run)")
        elif p.name not in listed and p.is_file():
            problems.append(f"extra: {p.name} (not in the manifest)")
    n = m["n_images"]
    if len(m["images"]) < n:
        problems.append(f"not rendered: {n - len(m['images'])} of {n} images")
    return problems, {"manifest": m, "complete": complete, "n_images": n}
