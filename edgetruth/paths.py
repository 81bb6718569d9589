"""Where shipped data lives: ``assets/`` and ``scenes/`` at the repository root."""
from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
ASSETS_DIR = REPO_ROOT / "assets"
SCENES_DIR = REPO_ROOT / "scenes"
RUNS_DIR = REPO_ROOT / "runs"
