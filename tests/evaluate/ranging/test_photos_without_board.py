"""Ranging photos without a calibration board: fx from a reference photo, or from EXIF.

The photos are analytic room photos (``render.synthetic.room_photos``: a dark 13 cm square printed on a
white sheet on a wooden door with a handle, a tape measure, a second sheet and a shadow; JPEG) seen by
a pinhole camera with fx = 800 px, so every error is measured against exact truth.
"""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from edgetruth.cli import main
from edgetruth.errors import InputError
from edgetruth.evaluate.ranging.focal_length import exif_fx, read_exif_focal
from edgetruth.render.synthetic.room_photos import RoomPhoto, render_room_photo

METHODS = "dynamic_erf_4p,canny_devernay"
FX = 800.0
#: (name, Z m, yaw deg, pitch deg); the first is the reference photo at 1 m, square-on
DESIGNS = [("ref_100.jpg", 1.0, 0.0, 0.0), ("t_060.jpg", 0.6, 10.0, 5.0), ("t_140.jpg", 1.4, -15.0, 8.0),
           ("t_190.jpg", 1.9, 5.0, -12.0), ("t_240.jpg", 2.4, 18.0, 0.0), ("t_290.jpg", 2.9, -8.0, -6.0)]


def _save_jpeg(path, img, exif_tags=None):
    from PIL import Image
    from PIL.TiffImagePlugin import IFDRational

    im = Image.fromarray(img)
    kw = {"quality": 92}
    if exif_tags:
        ex = Image.Exif()
        sub = ex.get_ifd(0x8769)
        for tag, v in exif_tags.items():
            sub[tag] = IFDRational(*v) if isinstance(v, tuple) else v
        kw["exif"] = ex.tobytes()
    im.save(path, **kw)


@pytest.fixture(scope="module")
def room_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("room")
    photos = root / "photos"
    photos.mkdir()
    truths = {}
    for k, (name, z, yaw, pitch) in enumerate(DESIGNS):
        img, truth = render_room_photo(RoomPhoto(kind="dark_square", z_m=z, x_m=0.03 * (-1) ** k, yaw_deg=yaw,
                                                 pitch_deg=pitch, jpeg_quality=None, seed=40 + k))
        # EXIF that implies the true fx: 4.25 mm x (800 / 4.25) px per mm, given per inch
        _save_jpeg(photos / name, img, {37386: (425, 100), 41486: (int(round(FX / 4.25 * 25.4 * 1000)), 1000),
                                        41488: 2})
        truths[name] = truth
    table = root / "distances.csv"
    with open(table, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["image", "distance_cm", "size_m", "shape", "group", "polarity"])
        for name, z, *_ in DESIGNS:
            w.writerow([name, f"{100 * z:g}", 0.13, "square", "room", "dark"])
    cal = root / "calibration.json"
    cal.write_text(json.dumps({"K": [[FX, 0, 319.5], [0, FX, 239.5], [0, 0, 1]], "dist_coeffs_opencv": [0.0] * 5,
                               "image_size": [640, 480]}))
    return root, photos, table, cal, truths


def _run(room_set, out, *extra, table=None):
    root, photos, tab, cal, _ = room_set
    return main(["evaluate", "--photos", str(photos), "--distances", str(table or tab), "-o", str(out), "-j", "1",
                 "--no-progress", "--methods", METHODS, *extra])


def _errors(out, method="dynamic_erf_4p"):
    with open(out / "ranging_rows.csv", newline="") as fh:
        return {r["image"]: float(r["error_cm"]) for r in csv.DictReader(fh) if r["method"] == method}


@pytest.fixture(scope="module")
def calibrated(room_set):
    out = room_set[0] / "calibrated"
    assert _run(room_set, out, "--calibration", str(room_set[3])) == 0
    return out


def test_a_reference_photo_ranges_as_well_as_the_board_calibration(room_set, calibrated):
    """fx from the photo at 1 m, the others ranged: the reference run's RMSE over the five test photos lies
    inside the 95 % bootstrap CI of the board-calibrated (true-K) run's, and each method's fx is within
    0.5 % of the true 800 px (its scale error at 1 m)."""
    from edgetruth.evaluate.stats import rmse_ci

    out = room_set[0] / "reference"
    assert _run(room_set, out, "--reference-photo", "ref_100.jpg") == 0
    e_ref, e_cal = _errors(out), _errors(calibrated)
    assert "ref_100.jpg" not in e_ref and len(e_ref) == 5  # the reference is out of the error tables
    tests = sorted(e_ref)
    a, b = np.array([e_ref[k] for k in tests]), np.array([e_cal[k] for k in tests])
    lo, hi = rmse_ci(b)
    assert lo <= math.sqrt(np.mean(a ** 2)) <= hi, (a, b, lo, hi)
    fx = json.loads((out / "reference_fx.json").read_text())
    for m in METHODS.split(","):
        assert fx[m]["fx_px"] == pytest.approx(FX, rel=0.005) and fx[m]["n"] == 1
    text = (out / "report.md").read_text()
    assert "## Focal length" in text and "ref_100.jpg" in text and "cancels" in text
    assert "reference: sets fx" in text


def test_the_csv_reference_column_is_the_same_as_the_option(room_set, tmp_path):
    root, photos, table, *_ = room_set
    t2 = tmp_path / "ref.csv"
    lines = table.read_text().splitlines()
    t2.write_text("\n".join([lines[0] + ",reference"] + [ln + (",yes" if ln.startswith("ref_") else ",")
                                                          for ln in lines[1:]]) + "\n")
    assert _run(room_set, tmp_path / "a", table=t2) == 0
    assert _run(room_set, tmp_path / "b", "--reference-photo", "ref_100.jpg") == 0
    assert _errors(tmp_path / "a") == pytest.approx(_errors(tmp_path / "b"), rel=1e-9)


def test_exif_focal_length_within_half_a_percent_of_what_the_tags_imply(tmp_path):
    """FocalLength with FocalLengthIn35mmFilm: the tags imply a sensor diagonal of 43.267 f / f35 mm; a
    4:3 sensor is 4/5 of it wide, so fx = f W / width.  With FocalPlaneXResolution: fx = f x px/mm."""
    img = np.full((480, 640), 128, np.uint8)
    p = tmp_path / "f35.jpg"
    _save_jpeg(p, img, {37386: (425, 100), 41989: 26})
    diag_mm = math.hypot(36, 24) * 4.25 / 26
    implied = 4.25 * 640 / (diag_mm * 0.8)
    fx, src = exif_fx(p, 640, 480)
    assert fx == pytest.approx(implied, rel=0.005) and "approximate" in src and "35" in src
    p2 = tmp_path / "fp.jpg"
    _save_jpeg(p2, img, {37386: (425, 100), 41486: (400, 1), 41488: 3})  # 400 px per cm = 40 px/mm
    assert exif_fx(p2, 640, 480)[0] == pytest.approx(4.25 * 40, rel=1e-9)


def test_exif_without_the_tags_or_with_zero_focal_length_is_one_clear_error(tmp_path):
    img = np.full((48, 64), 128, np.uint8)
    _save_jpeg(tmp_path / "none.jpg", img)
    assert read_exif_focal(tmp_path / "none.jpg") == {}
    with pytest.raises(InputError, match="no focal length"):
        exif_fx(tmp_path / "none.jpg", 64, 48, "none.jpg")
    _save_jpeg(tmp_path / "zero.jpg", img, {37386: (0, 1), 41989: 26})
    with pytest.raises(InputError, match="zero"):
        exif_fx(tmp_path / "zero.jpg", 64, 48, "zero.jpg")
    _save_jpeg(tmp_path / "f_only.jpg", img, {37386: (425, 100)})
    with pytest.raises(InputError, match="sensor's size is unknown"):
        exif_fx(tmp_path / "f_only.jpg", 64, 48, "f_only.jpg")


def test_exif_run_ranges_with_the_tags_fx(room_set, calibrated):
    """The photos' EXIF implies the true fx: the EXIF run's rows are the calibrated run's (same K, but for
    the tag's px per inch rounded to 1/1000: fx to ~1e-7, a Z error of ~1e-7 Z, 3e-5 cm at 3 m)."""
    out = room_set[0] / "exif"
    assert _run(room_set, out, "--exif-focal-length") == 0
    assert _errors(out) == pytest.approx(_errors(calibrated), abs=1e-4)
    text = (out / "report.md").read_text()
    assert "EXIF" in text and "approximate" in text


def _snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("what", ["roi outside", "reference distance differs", "exif zero focal", "exif missing",
                                  "point outside roi", "roi three numbers", "roi zero width", "reference word",
                                  "reference not in csv"])
def test_bad_input_is_one_line_exit_2_and_nothing_written(room_set, calibrated, tmp_path, capsys, what):
    root, photos, table, cal, _ = room_set
    extra, t = [], table
    if what == "roi outside":
        t = tmp_path / "roi.csv"
        t.write_text('image,distance_cm,size_m,shape,group,roi_px\nt_140.jpg,140,0.13,square,g,"600,400,100,100"\n')
        extra = ["--calibration", str(cal)]
        words = ["line 2", "roi_px", "leaves the 640 x 480"]
    elif what == "point outside roi":
        t = tmp_path / "pt.csv"
        t.write_text('image,distance_cm,size_m,shape,group,roi_px,point_px\n'
                     't_140.jpg,140,0.13,square,g,"10,10,100,100","300,200"\n')
        extra = ["--calibration", str(cal)]
        words = ["line 2", "outside its roi_px"]
    elif what in ("roi three numbers", "roi zero width", "reference word"):
        t = tmp_path / "cols.csv"
        cell = {"roi three numbers": ('"1,2,3"', ""), "roi zero width": ('"1 2 0 5"', ""),
                "reference word": ("", "maybe")}[what]
        t.write_text(f"image,distance_cm,size_m,shape,group,roi_px,reference\nt_140.jpg,140,0.13,square,g,{cell[0]},"
                     f"{cell[1]}\n")
        extra = ["--calibration", str(cal)]
        words = ["line 2", {"roi three numbers": "not 4 numbers", "roi zero width": "width or height <= 0",
                            "reference word": "write yes"}[what]]
    elif what == "reference not in csv":
        extra = ["--reference-photo", "elsewhere.jpg"]
        words = ["not found"]
    elif what == "reference distance differs":
        extra = ["--reference-photo", "t_140.jpg=100"]
        words = ["test photo at 140 cm", "not 100 cm"]
    else:
        sub = tmp_path / "p"
        sub.mkdir()
        img = np.full((480, 640), 128, np.uint8)
        _save_jpeg(sub / "a.jpg", img, {37386: (0, 1), 41989: 26} if what == "exif zero focal" else None)
        t = tmp_path / "e.csv"
        t.write_text("image,distance_cm,size_m,shape,group\n" + str(sub / "a.jpg") + ",100,0.13,square,g\n")
        extra = ["--exif-focal-length"]
        words = ["line 2", "zero" if what == "exif zero focal" else "no focal length"]
    before = _snapshot(calibrated)
    capsys.readouterr()
    assert _run(room_set, calibrated, *extra, table=t) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and all(w in err for w in words), err
    assert _snapshot(calibrated) == before
    assert _run(room_set, tmp_path / "new", *extra, table=t) == 2
    assert not (tmp_path / "new").exists()
