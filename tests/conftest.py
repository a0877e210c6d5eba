"""Shared fixtures for the language tests: where the example tasks live, and a scratch copy of them."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
TASKS_DIR = REPO / "tasks"
DOCS_DIR = REPO / "docs"


@pytest.fixture(scope="session")
def tasks_dir() -> Path:
    """The repository's ``tasks/`` directory (example tasks, their YAML scenes, ``library/``)."""
    return TASKS_DIR


@pytest.fixture
def tasks_copy(tmp_path: Path) -> Path:
    """A scratch copy of ``tasks/`` (scenes and ``library/`` included), so a test may edit files in it."""
    target = tmp_path / "tasks"
    shutil.copytree(TASKS_DIR, target)
    return target
