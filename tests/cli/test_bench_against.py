"""``edgetruth bench --against REV``: each side imports its own tree (workers included), the main
job's stage line is read back, bad revisions are one-line input errors, and (slow) a real side-by-side
render of one full-study image against HEAD."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from edgetruth.cli import main
from edgetruth.cli.commands import bench_against as ba


def _fake_tree(root, tag):
    (root / "edgetruth").mkdir(parents=True)
    (root / "edgetruth" / "__init__.py").write_text(f"TAG = {tag!r}\n")
    (root / "render").mkdir()
    (root / "render" / "__init__.py").write_text(f"TAG = {tag!r} + '/render'\n")
    return root


CHILD = """
import multiprocessing as mp
def probe(_):
    import edgetruth, edgetruth.render
    return edgetruth.TAG, edgetruth.render.TAG, edgetruth.render.__file__
if __name__ == "__main__":
    import edgetruth.render
    print(probe(0))
    with mp.get_context("spawn").Pool(1) as p:  # the backends' start method
        print(p.map(probe, [0])[0])
"""


def test_each_side_imports_its_own_tree_in_spawned_workers_too(tmp_path):
    tree = _fake_tree(tmp_path / "tree", "fake")
    env = ba.side_env(tree, tmp_path / "scratch")
    (tmp_path / "child.py").write_text(CHILD)
    out = subprocess.run([sys.executable, str(tmp_path / "child.py")], env=env, capture_output=True, text=True,
                         cwd=tmp_path, check=True).stdout.splitlines()
    assert len(out) == 2
    for line in out:  # not the venv's editable install of this checkout
        assert line.startswith("('fake', 'fake/render', ") and str(tree / "render") in line
    assert env["NUMBA_CACHE_DIR"].startswith(str(tmp_path / "scratch"))


def test_run_line_is_parsed_per_stage():
    text = ("render: ...\nrun: report /x/report.md (281.4 s in all: render_s 186.0, calibrate_s 3.5, "
            "thresholds_s 2.0, synthetic_s 50.1, ranging_s 37.2)\n")
    assert ba.parse_run_line(text) == {"total_s": 281.4, "render_s": 186.0, "calibrate_s": 3.5, "thresholds_s": 2.0,
                                       "synthetic_s": 50.1, "ranging_s": 37.2}
    with pytest.raises(RuntimeError):
        ba.parse_run_line("no such line")


def test_ratio_table_is_baseline_over_working():
    lines = ba.table_lines("t", [{"a": 10.0}, {"a": 30.0}, {"a": 20.0}], [{"a": 5.0}], ["a"])
    assert lines[2].split() == ["a", "20.00", "5.00", "4.00x"]


def test_unknown_revision_is_a_one_line_input_error(capsys, tmp_path, monkeypatch):
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    assert main(["bench", "--against", "no-such-rev-19", "--only", "render"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--against no-such-rev-19" in err
    assert list(tmp_path.iterdir()) == []  # no temporary folder left behind


def test_only_run_times_both_main_jobs_cold_against_their_goals(monkeypatch, capsys):
    """``bench --only run`` without --against (issue 49: it used to refuse): ``make run`` and the full study, each
    from a fresh copy of the tree, with --limit/--skip-synthetic passed on, and a line per job with its goal."""
    from edgetruth.cli.commands import bench_run

    calls = []

    def fake_job(tree, scratch, run_args, study="quick"):
        calls.append((Path(tree).name, study, list(run_args)))
        assert (Path(tree) / "pyproject.toml").is_file() and not list(Path(tree).rglob("__pycache__"))
        return {"total_s": 1.0, "render_s": 0.5, "wall_s": 1.5}

    monkeypatch.setattr(bench_run, "main_job_once", fake_job)
    assert main(["bench", "--only", "run", "--limit", "1", "--skip-synthetic"]) == 0
    assert calls == [("working", "quick", ["--limit", "1", "--skip-synthetic"]),
                     ("working", "full", ["--limit", "1", "--skip-synthetic"])]
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and "goal <= 60 s" in out[0] and "goal <= 180 s" in out[1] and "render_s 0.5" in out[0]


@pytest.mark.slow
def test_against_head_renders_one_image_per_side(fast_variant, capsys, tmp_path):
    """HEAD against itself: both sides render the same image (of a tiny spec: the path is the study's,
    its cost is not the point); the worktree is gone afterwards."""
    from edgetruth.render.testing import write_tiny_spec

    root = ba.repo_root()
    before = subprocess.run(["git", "-C", str(root), "worktree", "list"], capture_output=True, text=True).stdout
    spec = write_tiny_spec(tmp_path, spp=4)
    res = ba.run_against("HEAD", parts=("render",), study_images=1, say=lambda s: None, spec=str(spec))
    b, w = res["render"]["baseline"][0], res["render"]["working"][0]
    assert b["names"] == w["names"] and b["s_per_image"] > 0 and w["s_per_image"] > 0
    assert any(line.strip().startswith("s_per_image") for line in res["lines"])
    after = subprocess.run(["git", "-C", str(root), "worktree", "list"], capture_output=True, text=True).stdout
    assert after == before


def test_working_side_is_a_fresh_copy_of_the_checkout(tmp_path):
    """The working tree's side runs from its tracked and untracked-not-ignored files (uncommitted edits
    included), without bytecode or ignored outputs; its environment leaves the venv's bytecode alone."""
    root = tmp_path / "repo"
    root.mkdir()
    git = lambda *a: subprocess.run(["git", "-C", str(root), *a], check=True, capture_output=True)  # noqa: E731
    git("init", "-q")
    (root / ".gitignore").write_text("__pycache__/\nruns/\n")
    (root / "pkg").mkdir()
    (root / "pkg" / "a.py").write_text("A = 1\n")
    (root / "gone.py").write_text("")
    git("add", ".")
    git("-c", "user.email=x@y", "-c", "user.name=x", "commit", "-qm", "x")
    (root / "pkg" / "a.py").write_text("A = 2\n")  # an uncommitted edit
    (root / "new.py").write_text("N = 1\n")  # untracked, not ignored
    (root / "gone.py").unlink()  # deleted in the working tree
    (root / "pkg" / "__pycache__").mkdir()
    (root / "pkg" / "__pycache__" / "a.cpython-311.pyc").write_bytes(b"x")
    (root / "runs").mkdir()
    (root / "runs" / "out.txt").write_text("ignored")
    dest = tmp_path / "copy"
    ba.copy_working_tree(root, dest)
    got = sorted(str(p.relative_to(dest)) for p in dest.rglob("*") if p.is_file())
    assert got == [".gitignore", "new.py", "pkg/a.py"]
    assert (dest / "pkg" / "a.py").read_text() == "A = 2\n"
    (dest / "pkg" / "__pycache__").mkdir()
    ba.drop_bytecode(dest)
    assert not (dest / "pkg" / "__pycache__").exists()
    env = ba.side_env(dest, tmp_path / "scratch")
    assert "PYTHONPYCACHEPREFIX" not in env
