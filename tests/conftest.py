"""Shared fixtures: where the example tasks live, a scratch copy of them, and a private library cache."""

from __future__ import annotations

import os
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


@pytest.fixture(scope="session", autouse=True)
def private_cache(tmp_path_factory) -> Path:
    """Generated libraries go to a cache of this test session, never the user's ~/.cache/vfdsl."""
    cache = tmp_path_factory.mktemp("vfdsl-cache")
    previous = os.environ.get("VFDSL_CACHE")
    os.environ["VFDSL_CACHE"] = str(cache)
    yield cache
    if previous is None:
        del os.environ["VFDSL_CACHE"]
    else:
        os.environ["VFDSL_CACHE"] = previous
