"""Result types: what a method returns (``Refinement``) and what users get (``EdgePoints``)."""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Refinement:
    """A method's answer for every candidate it was given (same order, same length).

    x, y : refined positions (OpenCV convention); converged : bool per point.
    nx, ny : the method's own normal if it estimates one (else the candidate's).
    extras : per-point float/int arrays (e.g. A, B, s, window, entropy, se).
    """

    x: np.ndarray
    y: np.ndarray
    converged: np.ndarray
    nx: np.ndarray | None = None
    ny: np.ndarray | None = None
    extras: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def from_offset(cls, cand, offset_px, converged=None, **extras) -> "Refinement":
        """Points p + offset * n along each candidate's normal."""
        mu = np.asarray(offset_px, dtype=np.float64)
        conv = np.ones(mu.shape, bool) if converged is None else np.asarray(converged, bool)
        return cls(cand.x + mu * cand.nx, cand.y + mu * cand.ny, conv, extras={"offset": mu, **extras})


@dataclass
class EdgePoints:
    """Refined edge points of one image.

    x, y : float64 (N,), OpenCV convention (pixel centres at integers)
    nx, ny : unit normal (dark -> bright)
    converged : bool (N,); points that did not converge keep the candidate pixel
    candidate_index : index of each point in the ``Candidates`` it came from
    extras : per-point arrays, also reachable as attributes (``pts.s``, ``pts.se``)
    elapsed_s : wall time of the refinement stage (after Canny)
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
        cols = {"x": self.x, "y": self.y, "nx": self.nx, "ny": self.ny,
                "converged": self.converged.astype(np.int8)}
        cols.update(self.extras)
        return cols

    def to_csv(self, path) -> None:
        """Write one row per point with a header (columns: docs/formats.md), atomically."""
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
