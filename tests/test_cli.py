"""The ``vfdsl`` command line: output formats, exit codes, diagnostics without tracebacks, help texts.

What a process shows (the output formats, help texts, --version, a relative path from another folder, a closed
pipe) is tested on the CLI run as a separate process (``python -m vfdsl.cli``), exactly as a user would; the
diagnostics and exit statuses of mistaken files and usage run ``vfdsl.cli.main`` in the test's process
(conftest.run_cli), without 2-3 s of a new interpreter's imports each.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from conftest import TASKS_DIR, run_cli

from vfdsl.cli import main

TASK_B = TASKS_DIR / "paper_b_virtual_rcm.vf"
DIAGNOSTIC = re.compile(r"^(?P<file>.+):(?P<line>\d+):(?P<column>\d+): error: (?P<message>.+)$", re.MULTILINE)


def vfdsl(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-P", "-m", "vfdsl.cli", *args], capture_output=True, text=True, check=False,
                          timeout=120, cwd=cwd)


def test_show_yaml():
    proc = vfdsl("show", str(TASK_B))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    data = yaml.safe_load(proc.stdout)
    assert data["name"] == "paper_b_virtual_rcm"
    assert [c["primitive"] for c in data["constraints"]] == ["stays_at", "cone", "joint_limits", "joint_speed"]
    assert "span: {file:" in proc.stdout            # spans are printed on one line each


def test_show_json():
    proc = vfdsl("show", str(TASK_B), "--format", "json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["name"] == "paper_b_virtual_rcm"
    assert data["params"][0]["value"]["xyz"] == pytest.approx([0.0, 0.0, 0.29])
    assert data["scene"]["period"] == pytest.approx(0.01)


def test_show_relative_path_from_another_directory():
    proc = vfdsl("show", "paper_b_virtual_rcm.vf", "--format", "json", cwd=TASKS_DIR)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["file"] == "paper_b_virtual_rcm.vf"


def test_main_returns_zero_and_prints(capsys):
    assert main(["show", str(TASK_B), "--format", "json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["name"] == "paper_b_virtual_rcm" and err == ""


MALFORMED = """\
task broken
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
require tpi stays_at([0, 0, 290]) within 1 um
"""


@pytest.mark.parametrize("text, line, column, message", [
    (MALFORMED, 5, 9, "unknown frame 'tpi'"),                                     # a name error
    (MALFORMED.replace("within 1 um", "within 1 um )"), 5, 47, "unexpected ')'"),   # a syntax error
    (MALFORMED.replace("tpi", "tip").replace("1 um", "1 deg"), 5, 42, "expected a length"),  # units
])
def test_malformed_file_exits_2_with_a_diagnostic(tmp_path, text, line, column, message):
    bad = tmp_path / "bad.vf"
    bad.write_text(text)
    proc = run_cli("show", str(bad))
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert "Traceback" not in proc.stderr
    match = DIAGNOSTIC.search(proc.stderr)
    assert match, proc.stderr
    assert proc.stderr.startswith(f"{bad}:{line}:{column}: error: ")
    assert message in match["message"]
    assert "^" in proc.stderr                                                     # the caret line


def test_malformed_scene_exits_2_pointing_into_the_yaml(tmp_path):
    (tmp_path / "t.vf").write_text(MALFORMED.replace("tpi", "tip") + 'scene "t.yaml"\n')
    (tmp_path / "t.yaml").write_text("period: 10 ms\nstart: [1, 2\n")
    proc = run_cli("show", str(tmp_path / "t.vf"))
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.startswith(f"{tmp_path / 't.yaml'}:")
    assert "malformed YAML" in proc.stderr


def test_main_returns_2_on_user_error(tmp_path, capsys):
    (tmp_path / "bad.vf").write_text(MALFORMED)
    assert main(["show", str(tmp_path / "bad.vf")]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith(f"{tmp_path / 'bad.vf'}:5:9: error: unknown frame 'tpi'")
    assert "hint: did you mean 'tip'?" in err


def test_nonexistent_file(tmp_path):
    missing = tmp_path / "no_such_task.vf"
    proc = run_cli("show", str(missing))
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip() == f"error: file not found: {missing}"


def test_directory_instead_of_a_file(tmp_path):
    proc = run_cli("show", str(tmp_path))
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.startswith("error: cannot read")


def test_library_instead_of_a_task():
    proc = run_cli("show", str(TASKS_DIR / "library" / "fixtures.vf"))
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert ":1:9: error: fixtures.vf is a library; load a task file" in proc.stderr


def test_closed_pipe_is_quiet():
    """`vfdsl show x.vf | head -1`: the reader goes away before the output is written; no traceback."""
    proc = subprocess.Popen([sys.executable, "-P", "-m", "vfdsl.cli", "show", str(TASK_B), "--format", "json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    proc.stderr.close()
    assert proc.wait(timeout=120) == 0
    assert "Traceback" not in err and "BrokenPipeError" not in err


def test_program_help():
    proc = vfdsl("--help")
    assert proc.returncode == 0
    assert proc.stdout.startswith("usage: vfdsl")
    assert "show" in proc.stdout
    assert "print the checked task" in proc.stdout
    assert "docs/language.md" in proc.stdout


def test_show_help():
    proc = vfdsl("show", "--help")
    assert proc.returncode == 0
    assert proc.stdout.startswith("usage: vfdsl show")
    assert "--format {yaml,json}" in proc.stdout
    assert "examples:" in proc.stdout
    assert "vfdsl show tasks/paper_b_virtual_rcm.vf" in proc.stdout


def test_version():
    proc = vfdsl("--version")
    assert proc.returncode == 0
    assert re.fullmatch(r"vfdsl \d+\.\d+\.\d+\s*", proc.stdout)


@pytest.mark.parametrize("args, message", [
    ((), "the following arguments are required: COMMAND"),
    (("show",), "the following arguments are required: file"),
    (("show", str(TASK_B), "--format", "xml"), "invalid choice: 'xml'"),
    (("frobnicate",), "invalid choice: 'frobnicate'"),
])
def test_usage_errors_exit_2(args, message):
    proc = run_cli(*args)
    assert proc.returncode == 2
    assert message in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("args", [
    ("show", ""), ("compile", str(TASK_B), "-o", ""), ("export", str(TASK_B), "-o", ""),
    ("export", str(TASK_B), "-o", "out", "--cache", ""), ("check", str(TASK_B), "--scene", ""),
    *(("simulate", str(TASK_B), option, "") for option in ("--scene", "--json", "--csv", "--plot", "--trace")),
    ("replay-trace", str(TASK_B), "", "r.txt", "-o", "run.csv"),
    ("replay-trace", str(TASK_B), "t.txt", "", "-o", "run.csv"),
    ("replay-trace", str(TASK_B), "t.txt", "r.txt", "-o", ""),
    ("replay-trace", str(TASK_B), "t.txt", "r.txt", "-o", "run.csv", "--params", ""),
    ("view", str(TASK_B), "--replay", ""), ("view", str(TASK_B), "--screenshot", ""),
])
def test_an_empty_path_is_a_usage_error(tmp_path, monkeypatch, capsys, args):
    """An empty file or folder name is refused before any work: `export -o ""` wrote into the current directory (its
    README.md and Makefile replaced), `simulate --json ""` wrote nothing, `check --scene ""` read the task's own."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "README.md").write_text("the user's")
    with pytest.raises(SystemExit) as exit_:
        main(list(args))
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "an empty path names no file or folder" in err, err
    assert [p.name for p in tmp_path.iterdir()] == ["README.md"]
    assert (tmp_path / "README.md").read_text() == "the user's"


def test_primitives_lists_every_argument_with_its_allowed_range(capsys):
    from vfdsl.objectives import OBJECTIVES
    from vfdsl.primitives import CONSTRAINTS
    assert main(["primitives"]) == 0
    out = capsys.readouterr().out
    for spec in [*CONSTRAINTS.values(), *OBJECTIVES.values()]:
        assert f" {spec.name}(...)" in out
        for arg in spec.args:
            if arg.range is not None:
                assert f"allowed {arg.range.describe()}" in out
    assert main(["primitives", "cone"]) == 0 and "allowed (0, 90) deg" in capsys.readouterr().out
    assert main(["primitives", "cnoe"]) == 2
    assert "did you mean 'cone'" in capsys.readouterr().err
    assert main(["primitives", ""]) == 2                 # an empty name listed every primitive, as if not given
    assert "no primitive or objective term ''" in capsys.readouterr().err
