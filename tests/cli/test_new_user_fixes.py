"""What a new user hit with the wheel (stop 43's walkthrough): messages that point at the real cause and the fix."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgetruth.cli import main
from edgetruth.errors import InputError
from edgetruth.render.testing import write_tiny_spec


def test_locate_refuses_a_method_that_needs_a_camera_model_with_the_alternative(tmp_path, capsys):
    img = np.full((60, 60), 40, np.uint8)
    cv2.circle(img, (30, 30), 15, 200, -1)
    cv2.imwrite(str(tmp_path / "d.png"), img)
    out = tmp_path / "p.csv"
    assert main(["locate", str(tmp_path / "d.png"), "-m", "patch_esf_fit", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "-m patch_esf_fit: it needs the camera's model" in err[0]
    assert "on photos use patch_psf_fit" in err[0] and not out.exists()


def test_edge_mode_frame_names_why_a_group_is_out_of_its_scope(tmp_path):
    """A preset target with a material of its own is a scene of its own: the message says so, rather than only
    "covers preset targets (T1..T4)" to a user whose group names T2."""
    from edgetruth.render.dataset.spec import load_spec

    spec = write_tiny_spec(tmp_path, modes='edge_mode = "frame"\n')
    spec.write_text(spec.read_text().replace('target = "T2"\n', 'target = "T2"\ntarget_material = { type = '
                                                                '"diffuse", albedo = 0.1 }\n', 1))
    with pytest.raises(InputError, match=r"group 'T2': edge_mode = \"frame\" covers the preset targets T1..T4 as "
                                         r"shipped and a static camera, and it has a scene of its own \(shapes, "
                                         r"a target_material or a texture\)"):
        load_spec(spec)


def test_calibrate_on_separate_squares_points_to_the_board_study(tmp_path):
    """Zhang's photos show separate squares: no inner corners for --pattern; the message names the study that
    reads them."""
    from edgetruth.evaluate.calibration import calibrate_photos

    photos = []
    for k in range(3):
        img = np.full((120, 160), 128, np.uint8)
        cv2.rectangle(img, (40 + k, 30), (70 + k, 60), 20, -1)  # one dark square: a board of squares has no corners
        cv2.imwrite(str(tmp_path / f"p{k}.png"), img)
        photos.append((f"p{k}.png", tmp_path / f"p{k}.png"))
    with pytest.raises(InputError, match=r"a board of separate squares \(zhang1998's\) has none: run `edgetruth "
                                         r"study board` on it"):
        calibrate_photos(photos, (9, 6), 0.025)
