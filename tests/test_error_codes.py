"""Front-end errors: every independent mistake of a file at once, sorted, each with its stable code.

The codes live in one table (vfdsl.errors.CODES), documented in docs/language.md ("Error codes"); every
place in the front end that makes an error gives it a code from that table. A mistake that other checks
depend on (a frame on an unknown link) is reported once, not again where it is used.
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import pytest
from conftest import run_cli

import vfdsl
from vfdsl.check.report import CODES as FINDING_CODES
from vfdsl.errors import CODES, VfError, VfErrors

REPO = Path(__file__).resolve().parent.parent
FRONT_END = sorted((REPO / "vfdsl" / "syntax").glob("*.py")) + sorted((REPO / "vfdsl" / "passes").glob("*.py")) \
    + [REPO / "vfdsl" / "units.py"]

# Four independent mistakes, written out of order of the checks (a clause before a declaration's value), and
# one that only follows from another: `tip` is on an unknown link, so `tip2` (built on it) and the constraint
# on `tip2` are not checked again.
SEVERAL = """\
task several
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tp")
frame tip2 = tip offset [0, 0, 1]
frame ok = shr.link("tool_tip")
param p : point = [0, 0, 290 deg]
param q : point = [0, 0, 290]
require tip2 stays_at(q) within 1 um resolution 4x4
require ok stays_at(q) within 1 deg resolution 4x4
minimize damping() weight -1
"""
EXPECTED = [   # line, column, code, message (a substring)
    (4, 22, "E201", "robot 'shr' has no link 'tool_tp'"),
    (7, 26, "E302", "expected a length, but 'deg' is an angle"),
    (10, 31, "E302", "expected a length, but 'deg' is an angle"),
    (11, 27, "E402", "a weight must be in"),
]


def load_error(tmp_path: Path, text: str) -> VfError:
    (tmp_path / "task.vf").write_text(text)
    with pytest.raises(VfError) as info:
        vfdsl.load(tmp_path / "task.vf")
    return info.value


def test_codes_are_unique_and_apart_from_checks_codes():
    source = (REPO / "vfdsl" / "errors.py").read_text()
    table = next(node.value for node in ast.walk(ast.parse(source))
                 if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", None) == "CODES")
    keys = [k.value for k in table.keys]
    assert len(keys) == len(set(keys)) == len(CODES)
    assert all(re.fullmatch(r"E[1-9]\d\d", code) for code in keys)
    assert len(set(CODES.values())) == len(CODES)
    assert not set(CODES) & set(FINDING_CODES.values())


def test_every_code_is_documented():
    documented = (REPO / "docs" / "language.md").read_text()
    assert all(f"| {code} | {meaning} |" in documented for code, meaning in CODES.items())


def _coded_sites(path: Path) -> list[tuple[int, str | None]]:
    """(line, code) of every error the module makes: VfError(...), limits.exceeded(...), error.with_code(...)."""
    sites = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.Call):
            continue
        name = getattr(node.func, "id", None) or getattr(node.func, "attr", None)
        if name in ("VfError", "exceeded"):
            given = next((k.value for k in node.keywords if k.arg == "code"), None)
        elif name == "with_code":
            given = node.args[0]
        else:
            continue
        sites.append((node.lineno, given.value if isinstance(given, ast.Constant) else None))
    return sites


@pytest.mark.parametrize("path", FRONT_END, ids=[p.name for p in FRONT_END])
def test_every_error_the_front_end_makes_has_a_code_from_the_table(path):
    bad = [(line, code) for line, code in _coded_sites(path) if code not in CODES]
    assert not bad, f"{path.name}: errors without a code of vfdsl.errors.CODES at {bad}"


def test_a_file_reports_every_independent_mistake_sorted_with_codes_and_carets(tmp_path):
    err = load_error(tmp_path, SEVERAL)
    assert isinstance(err, VfErrors)
    found = [(e.pos.line, e.pos.column, e.code, e.message) for e in err.errors]
    assert [f[:3] for f in found] == [e[:3] for e in EXPECTED]
    assert all(expected[3] in message for expected, (*_, message) in zip(EXPECTED, found))
    assert (err.message, err.pos, err.code) == (err.errors[0].message, err.errors[0].pos, "E201")   # the first
    rendered = err.render()
    heads = [line for line in rendered.splitlines() if ": error: " in line]
    assert [tuple(map(int, h.split(":")[1:3])) for h in heads] == [e[:2] for e in EXPECTED]
    assert rendered.count("^") >= len(EXPECTED) and rendered.endswith(f"\n\n{len(EXPECTED)} errors")
    for code in ("E201", "E302", "E402"):
        assert f"code: {code}, {CODES[code]}" in rendered
    assert str(err) == rendered


CORRECTED = SEVERAL.replace('"tool_tp"', '"tool_tip"').replace("290 deg", "290").replace("1 deg", "1 um") \
    .replace("weight -1", "weight 1")


def test_the_corrected_file_loads(tmp_path):
    (tmp_path / "task.vf").write_text(CORRECTED)
    assert vfdsl.load(tmp_path / "task.vf").name == "several"


def test_what_follows_from_a_failed_declaration_is_not_reported(tmp_path):
    text = CORRECTED.replace('frame ok = shr.link("tool_tip")', 'frame ok = shr.link("tool_tip") offset [0, 0]')
    err = load_error(tmp_path, text + "require ok stays_at(p)\n")
    assert len(err.errors) == 1 and err.code == "E401" and err.pos.line == 6   # not `ok`'s two uses


def test_a_fixture_whose_formals_are_wrong_is_reported_once(tmp_path):
    err = load_error(tmp_path, CORRECTED + "fixture f(a: frame, a: point) {\n    require a stays_at(q)\n}\n"
                     "use f(tip, q)\nuse f(ok, q)\nuse g()\n")
    assert [(e.pos.line, e.code) for e in err.errors] == [(12, "E202"), (17, "E201")]


def test_a_single_error_is_one_error_with_its_code(tmp_path):
    err = load_error(tmp_path, SEVERAL.split("frame tip2")[0])
    assert type(err) is VfError and err.errors == (err,) and err.code == "E201"
    assert err.render().splitlines()[-1] == f"code: E201, {CODES['E201']}"


@pytest.mark.parametrize("command", ["compile", "check"])
def test_cli_prints_every_error_and_exits_2(tmp_path, command):
    (tmp_path / "task.vf").write_text(SEVERAL)
    proc = run_cli(command, str(tmp_path / "task.vf"))
    assert proc.returncode == 2 and proc.stdout == "" and "Traceback" not in proc.stderr
    heads = re.findall(r"^.+:(\d+):(\d+): error: ", proc.stderr, re.MULTILINE)
    assert [tuple(map(int, h)) for h in heads] == [e[:2] for e in EXPECTED]
    assert proc.stderr.rstrip().endswith(f"{len(EXPECTED)} errors")


def test_check_json_has_a_finding_per_error_with_its_code(tmp_path):
    (tmp_path / "task.vf").write_text(SEVERAL)
    proc = run_cli("check", str(tmp_path / "task.vf"), "--json")
    assert proc.returncode == 2
    findings = json.loads(proc.stdout)["findings"]
    assert [f["code"] for f in findings] == ["VF000"] * len(EXPECTED)
    assert [(f["location"]["line"], f["data"]["error_code"]) for f in findings] == [(e[0], e[2]) for e in EXPECTED]
