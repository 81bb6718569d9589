"""`make docs` builds: the site, offline and in strict mode (a broken link, a missing page, a docstring griffe
cannot parse fails it), so CI catches a broken page."""
from __future__ import annotations

import subprocess
import sys

from tests.support.tools import ROOT


def test_docs_site_builds_strict(tmp_path):
    pytest = __import__("pytest")
    pytest.importorskip("mkdocs", reason="the docs packages are in the test extra: pip install -e '.[test]'")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(tmp_path / "site")],
                       cwd=ROOT, capture_output=True, text=True, timeout=600,
                       env={**__import__("os").environ, "NO_MKDOCS_2_WARNING": "1"})
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-4000:]
    site = tmp_path / "site"
    assert (site / "index.html").is_file()
    # the API reference rendered the docstrings' sections (numpydoc Parameters / Returns)
    ref = (site / "reference" / "locate.html").read_text()
    assert "Parameters" in ref and "Returns" in ref
    assert (site / "tutorials" / "sweep.html").read_text().count("synthetic_image") >= 1  # the script included
