"""The README's examples work as written: its task file loads and compiles, and its Python snippet runs."""

from __future__ import annotations

import re

import numpy as np
from conftest import REPO

import vfdsl

BLOCKS = re.findall(r"```(\w*)\n(.*?)```", (REPO / "README.md").read_text(), flags=re.DOTALL)


def test_readme_task_loads_and_holds_the_pivot(tmp_path):
    (task_text,) = [text for lang, text in BLOCKS if text.startswith("task ")]
    path = tmp_path / "readme.vf"
    path.write_text(task_text)
    task = vfdsl.load(path)
    ctrl = vfdsl.compile(task, backend="interpreted")
    start = vfdsl.load(REPO / "tasks" / "paper_b_virtual_rcm.vf").start
    dq = ctrl.step(start, {"tau": [0.0, 0.0, 0.01]}, dt=0.01)
    assert np.all(np.isfinite(dq)) and ctrl.violations() == []


def test_readme_python_snippet_runs(monkeypatch):
    (snippet,) = [text for lang, text in BLOCKS if lang == "python"]
    monkeypatch.chdir(REPO)
    namespace: dict = {}
    exec(compile(snippet, "README.md", "exec"), namespace)
    assert namespace["dq"].shape == (7,)
    assert namespace["qp"].labels[-1].startswith("cone(tip)")
