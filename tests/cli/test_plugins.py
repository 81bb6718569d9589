"""User methods: registered by a plug-in module, an entry point or in the calling script; they run in
pool workers and appear in every table next to the built-in methods."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from edgetruth.cli import main

SUPPORT = Path(__file__).resolve().parents[1] / "support"
PLUGIN = SUPPORT / "plugin_method.py"


def _true_calibration(dataset: Path, path: Path) -> Path:
    """A calibration.json with the true intrinsics (the tiny dataset has one board: too few for Zhang)."""
    from edgetruth.render import open_dataset

    cam = open_dataset(dataset)[0].truth["camera"]
    path.write_text(json.dumps({"K": cam["K"], "dist_coeffs_opencv": cam["dist_coeffs_opencv"],
                                "image_size": [cam["width_px"], cam["height_px"]]}))
    return path


def test_plugin_method_runs_in_two_pool_workers_and_fills_the_synthetic_tables(tmp_path, capsys):
    out = tmp_path / "study"
    rc = main(["study", "synthetic", "--images-per-scenario", "2", "-j", "2", "--plugin", str(PLUGIN),
               "--methods", "canny_pixel,user_gradient_centroid,dynamic_erf_4p", "-o", str(out), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    report = (out / "report.md").read_text()
    table6 = report.split("## Table 6")[1].split("## ")[0]
    table8 = report.split("## Table 8")[1].split("## ")[0]
    assert "UserGradientCentroid" in table6 and "UserGradientCentroid" in table8 and "CannyPixel" in table6
    rows = (out / "tables" / "table6_all_methods.csv").read_text()
    assert "user_gradient_centroid" in rows


def test_plugin_method_in_the_ranging_report_with_two_workers(tiny_dataset, tmp_path, capsys):
    _, data = tiny_dataset
    cal = _true_calibration(data, tmp_path / "cal.json")
    out = tmp_path / "eval"
    rc = main(["evaluate", str(data), "--calibration", str(cal), "-j", "2", "--plugin", str(PLUGIN),
               "--methods", "canny_pixel,user_gradient_centroid,dynamic_erf_4p", "-o", str(out), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    table13 = (out / "report.md").read_text().split("## Table 13")[1].split("## ")[0]
    assert "UserGradientCentroid" in table13 and "ProposedDynamicERF_4P" in table13
    rows = (out / "ranging_rows.csv").read_text().splitlines()
    assert sum(",user_gradient_centroid," in r for r in rows) == 2  # one per target image


def test_entry_point_method_is_found_by_every_process(tiny_dataset, tmp_path):
    """A package declaring an `edgetruth.methods` entry point: no --plugin needed, in the driver or in
    its workers (a subprocess, so the entry point is seen from a clean start)."""
    site = tmp_path / "site"
    dist = site / "user_edges-1.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: user-edges\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[edgetruth.methods]\nuser_ep_centroid = user_edges:refine\n")
    (site / "user_edges.py").write_text(
        PLUGIN.read_text().replace('@locate.register("user_gradient_centroid", label="UserGradientCentroid")\n', "")
        .replace("def user_gradient_centroid(", "def refine("))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]))
    cmd = [sys.executable, "-m", "edgetruth"]
    r = subprocess.run(cmd + ["methods"], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0 and "user_ep_centroid" in r.stdout, r.stderr
    _, data = tiny_dataset
    cal = _true_calibration(data, tmp_path / "cal.json")
    out = tmp_path / "eval"
    r = subprocess.run(cmd + ["-q", "evaluate", str(data), "--calibration", str(cal), "-j", "2", "--methods",
                              "canny_pixel,user_ep_centroid", "-o", str(out)], capture_output=True, text=True,
                       env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout == "" and r.stderr == "", "-q prints nothing on success"
    assert "user_ep_centroid" in (out / "report.md").read_text().split("## Table 13")[1]


SCRIPT = '''
import sys
import numpy as np
from edgetruth import locate
from edgetruth.evaluate.synthetic.study import run_synthetic_study

if __name__ == "__main__":
    @locate.register("main_half_offset", label="MainHalfOffset")   # defined only in __main__
    def main_half_offset(image, cand):
        return locate.Refinement.from_offset(cand, np.full(len(cand), 0.5))

    rep = run_synthetic_study(sys.argv[1], images_per_scenario=2, workers=2, progress=False,
                              methods=["canny_pixel", "main_half_offset"])
    print(open(rep).read().count("MainHalfOffset"))
'''


def test_method_registered_under_main_runs_in_spawn_workers(tmp_path):
    script = tmp_path / "user_script.py"
    script.write_text(SCRIPT)
    r = subprocess.run([sys.executable, str(script), str(tmp_path / "s")], capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert int(r.stdout.strip().splitlines()[-1]) >= 2  # in Table 6 and Table 8


@pytest.mark.parametrize("argv, expect", [
    (["methods", "--plugin", "no_such_module_xyz"], "no module named"),
    (["methods", "--plugin", "/no/such/file.py"], "no such file"),
])
def test_bad_plugin_is_one_line(argv, expect, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expect in err[0]


@pytest.fixture
def isolated_plugins(monkeypatch):
    """The registry, the loaded plug-ins and sys.path as they were before the test (later tests run
    'all methods' and start workers that import every loaded plug-in)."""
    from edgetruth.locate import plugins, registry

    monkeypatch.setattr(plugins, "_loaded", {})
    monkeypatch.setattr(plugins, "_path_added", [])
    monkeypatch.setattr(sys, "path", list(sys.path))
    saved = dict(registry.METHODS)
    yield
    registry.METHODS.clear()
    registry.METHODS.update(saved)
    sys.modules.pop("my_edges_cwd", None)
    sys.modules.pop("broken_dep_mod", None)


def test_plugin_by_module_name_from_its_own_folder(tmp_path, monkeypatch, capsys, isolated_plugins):
    """`--plugin my_edges` run from the folder that holds my_edges.py imports it, as `python -m` would;
    workers, which may start elsewhere, get its file."""
    (tmp_path / "my_edges_cwd.py").write_text(PLUGIN.read_text().replace("user_gradient_centroid",
                                                                          "user_cwd_centroid"))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", ".", str(tmp_path))])
    rc = main(["methods", "--plugin", "my_edges_cwd"])
    assert rc == 0, capsys.readouterr().err
    assert "user_cwd_centroid" in capsys.readouterr().out
    from edgetruth.locate.plugins import worker_payload

    refs, _ = worker_payload(["user_cwd_centroid"])
    assert refs == (str(tmp_path / "my_edges_cwd.py"),)


def test_plugin_errors_name_the_real_cause(tmp_path, monkeypatch, capsys, isolated_plugins):
    monkeypatch.chdir(tmp_path)
    assert main(["methods", "--plugin", "no_such_module_xyz"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no module named 'no_such_module_xyz'" in err and str(tmp_path) in err
    (tmp_path / "broken_dep_mod.py").write_text("import not_installed_dependency_xyz\n")
    assert main(["methods", "--plugin", "broken_dep_mod"]) == 2
    err = capsys.readouterr().err.strip()
    assert "not_installed_dependency_xyz" in err and "inside it" in err


BROKEN_METHODS = '''
import numpy as np
from edgetruth import locate


@locate.register("raises_inside")
def raises_inside(image, cand):
    raise RuntimeError("kaboom\\nsecond line")


@locate.register("too_few")
def too_few(image, cand):
    return locate.Refinement.from_offset(cand, np.zeros(3))  # three offsets for every candidate


@locate.register("returns_none")
def returns_none(image, cand):
    return None
'''


@pytest.mark.parametrize("method, expect", [
    ("raises_inside",
     "method 'raises_inside' ({path}) raised RuntimeError: kaboom -- on {n} candidates; fix the method"),
    ("too_few", "method 'too_few' ({path}) raised ValueError: "),
    ("returns_none", "method 'returns_none' ({path}) returned NoneType, not a Refinement; return Refinement("),
])
def test_a_failing_plugin_method_is_one_line_naming_it_and_the_image(method, expect, tmp_path, capsys,
                                                                      isolated_plugins):
    """A user's method that raises, breaks the one-entry-per-candidate contract or returns no Refinement: one line
    on stderr naming the image, the method and its file, exit 2, and no CSV half-written."""
    import cv2
    import numpy as np

    plug = tmp_path / "broken_methods.py"
    plug.write_text(BROKEN_METHODS)
    img = np.full((80, 80), 50, np.uint8)
    cv2.circle(img, (40, 40), 20, 200, -1)
    cv2.imwrite(str(tmp_path / "disc.png"), cv2.GaussianBlur(img, (0, 0), 1.2))
    from edgetruth import locate

    n = len(locate.candidates(cv2.imread(str(tmp_path / "disc.png"), cv2.IMREAD_GRAYSCALE).astype(float)))
    out = tmp_path / "pts.csv"
    assert main(["locate", str(tmp_path / "disc.png"), "-m", method, "--plugin", str(plug), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("edgetruth locate: error: ") and "disc.png: " in err[0]
    assert expect.format(path=plug, n=n) in err[0], err[0]
    assert not out.exists()


def test_a_wrong_length_answer_is_caught_where_it_is_made():
    """``check_refinement``: every per-candidate field, extras included, has one entry per candidate."""
    import numpy as np

    from edgetruth.errors import InputError
    from edgetruth.locate.registry import METHODS, check_refinement
    from edgetruth.locate.result import Refinement

    m = METHODS["erf4p_fixed11"]
    ok = Refinement(np.zeros(5), np.zeros(5), np.ones(5, bool), extras={"s": np.zeros(5)})
    check_refinement(m, ok, 5)
    with pytest.raises(InputError, match=r"returned extras\['s'\] of shape \(4,\) for 5 candidates"):
        check_refinement(m, Refinement(np.zeros(5), np.zeros(5), np.ones(5, bool), extras={"s": np.zeros(4)}), 5)
    with pytest.raises(InputError, match=r"returned nx of shape \(5, 2\)"):
        check_refinement(m, Refinement(np.zeros(5), np.zeros(5), np.ones(5, bool), nx=np.zeros((5, 2))), 5)
