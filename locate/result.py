"""Result types: what a method returns (``Refinement``) and what users get (``EdgePoints``)."""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Refinement:
    """A method's answer: one entry per candidate it was given, in the same order.

    Attributes
    ----------
    x, y : numpy.ndarray
        (N,) refined positions, px, OpenCV convention.
    converged : numpy.ndarray
        (N,) bool: False where the method declined the candidate (the point then stays at its pixel).
    nx, ny : numpy.ndarray or None
        (N,) the method's own unit normal, dark to bright, if it estimates one (else the candidate's).
    extras : dict of str to numpy.ndarray
        Per-point arrays (e.g. ``A``, ``B``, ``s``, ``window``, ``entropy``, ``se``), written as CSV columns.
    """

    x: np.ndarray
    y: np.ndarray
    converged: np.ndarray
    nx: np.ndarray | None = None
    ny: np.ndarray | None = None
    extras: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def from_offset(cls, cand, offset_px, converged=None, **extras) -> "Refinement":
        """Points p + offset n along each candidate's normal.

        Parameters
        ----------
        cand : Candidates
            The candidates the offsets belong to.
        offset_px : array_like
            (N,) offsets along each normal, px, > 0 towards the bright side.
        converged : array_like, optional
            (N,) bool (default: all True).
        **extras
            Per-point arrays to carry along (as ``Refinement.extras``; ``offset`` is added).

        Returns
        -------
        Refinement
            The refined points.
        """
        mu = np.asarray(offset_px, dtype=np.float64)
        conv = np.ones(mu.shape, bool) if converged is None else np.asarray(converged, bool)
        return cls(cand.x + mu * cand.nx, cand.y + mu * cand.ny, conv, extras={"offset": mu, **extras})


@dataclass
class EdgePoints:
    """Refined edge points of one image, what ``locate`` and ``refine`` return.

    Attributes
    ----------
    method : str
        The method id.
    x, y : numpy.ndarray
        float64 (N,), px, OpenCV convention (pixel centres at integers).
    nx, ny : numpy.ndarray
        float64 (N,): the unit normal, dark to bright.
    converged : numpy.ndarray
        bool (N,): points that did not converge keep the candidate pixel.
    candidate_index : numpy.ndarray
        The index of each point in the ``Candidates`` it came from.
    extras : dict of str to numpy.ndarray
        Per-point arrays, also reachable as attributes (``pts.s``, ``pts.se``, px).
    elapsed_s : float
        Wall time of the refinement stage (after Canny), s.
    """

    method: str
    x: np.ndarray
    y: np.ndarray
    nx: np.ndarray
    ny: np.ndarray
    converged: np.ndarray
    candidate_index: np.ndarray
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    elapsed_s: float = 0.0

    def __len__(self) -> int:
        return int(self.x.shape[0])

    def __getattr__(self, name):
        extras = self.__dict__.get("extras", {})
        if name in extras:
            return extras[name]
        raise AttributeError(f"EdgePoints has no field {name!r}; extras are {sorted(extras)}")

    def columns(self) -> dict[str, np.ndarray]:
        """The CSV's columns: ``x``, ``y``, ``nx``, ``ny``, ``converged`` (0/1), then the extras.

        Returns
        -------
        dict of str to numpy.ndarray
            Column name -> (N,) values.
        """
        cols = {"x": self.x, "y": self.y, "nx": self.nx, "ny": self.ny,
                "converged": self.converged.astype(np.int8)}
        cols.update(self.extras)
        return cols

    def to_csv(self, path) -> None:
        """Write one row per point with a header (columns: docs/formats.md), atomically.

        Parameters
        ----------
        path : str or pathlib.Path
            The CSV file (replaced whole; a failed write leaves the old one).
        """
        from edgetruth.fileio import atomic_write_text

        cols = self.columns()
        names = list(cols)
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(names)
        data = [np.asarray(cols[n]) for n in names]
        for i in range(len(self)):
            w.writerow([_fmt(d[i]) for d in data])
        atomic_write_text(Path(path), buf.getvalue())


def _fmt(v) -> str:
    if isinstance(v, (np.integer, int, np.bool_, bool)):
        return str(int(v))
    return repr(float(v))
