"""docs/formats.md lists every column and key the code writes (so the documentation cannot drift)."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = (ROOT / "docs" / "formats.md").read_text()
# the sensor and camera parameters a ground truth records are the spec keys of docs/spec.md
DOCUMENTED = set(re.findall(r"`([A-Za-z_][A-Za-z0-9_]*)`", DOC + (ROOT / "docs" / "spec.md").read_text()))


def test_every_locate_csv_column_of_every_builtin_method_is_documented():
    from edgetruth import locate
    from edgetruth.render.synthetic import synthetic_image

    s = synthetic_image("ideal", 0, split="unit")
    cand = locate.candidates(s.image)
    missing = {}
    for m, rec in locate.METHODS.items():
        if not rec.builtin:
            continue
        cols = set(locate.refine(s.image, cand, m).columns())
        if cols - DOCUMENTED:
            missing[m] = sorted(cols - DOCUMENTED)
    assert not missing, missing


def test_every_ground_truth_and_manifest_key_is_documented(tiny_dataset):
    from edgetruth.render import open_dataset

    ds = open_dataset(tiny_dataset[1])
    keys = set()
    for s in ds:
        gt = s.truth
        keys |= set(gt)
        for k in ("camera", "pose", "target", "outline", "illumination", "sensor", "render", "versions",
                  "checkerboard", "corners", "seeds"):
            if isinstance(gt.get(k), dict):
                keys |= set(gt[k])
    keys |= set(ds.manifest)
    entry = next(iter(ds.manifest["images"].values()))
    keys |= set(entry)
    missing = sorted(keys - DOCUMENTED)
    assert not missing, missing


def test_every_ranging_row_field_is_documented():
    from edgetruth.evaluate.ranging.images import ROW_FIELDS

    assert not sorted(set(ROW_FIELDS) - DOCUMENTED)
