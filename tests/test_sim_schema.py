"""The simulation scene's documentation: docs/simulate.schema.json is the generated schema; every example in
docs/simulate.md validates against it and loads against its task; together they use every key and kind the
reader accepts; and a key the schema refuses in a section, the reader refuses there too."""

from __future__ import annotations

import json
import re

import pytest
import yaml
from conftest import TASKS_DIR

import vfdsl
from vfdsl.cli import main
from vfdsl.errors import VfError
from vfdsl.sim import scene_file
from vfdsl.sim import settings as s
from vfdsl.sim.schema import DISTURBANCE_KEYS, scene_schema
from vfdsl.sim.scene_file import load_settings

DOCS = TASKS_DIR.parent / "docs"
EXAMPLE = re.compile(r"```yaml\n# task: (\S+)[^\n]*\n(.*?)```", re.S)


def _examples() -> list[tuple[str, str]]:
    return EXAMPLE.findall((DOCS / "simulate.md").read_text())


def _validator():
    jsonschema = pytest.importorskip("jsonschema")
    return jsonschema.Draft202012Validator(scene_schema())


def test_the_schema_file_is_the_generated_schema():
    assert (DOCS / "simulate.schema.json").read_text() == json.dumps(scene_schema(), indent=2) + "\n"


def test_the_schema_is_a_valid_json_schema():
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.Draft202012Validator.check_schema(scene_schema())


@pytest.mark.parametrize("task, text", _examples())
def test_every_example_validates_and_loads(tmp_path, task, text):
    doc = yaml.safe_load(text)
    assert not list(_validator().iter_errors(doc))
    scene = tmp_path / "x.sim.yaml"
    scene.write_text(text)
    if "recording" in doc:                  # its bag, written where the example says (the task's input and joints)
        from test_recording import _joints, _write_joint_bag, write_bag
        bag = tmp_path / doc["recording"]["bag"]
        bag.parent.mkdir(parents=True, exist_ok=True)
        if any(isinstance(source, dict) for source in doc["recording"].get("inputs", {}).values()):
            from vfdsl.kinematics.robot import Robot
            loaded = vfdsl.load(TASKS_DIR.parent / task)
            _write_joint_bag(bag, Robot.load(loaded.robots[0].urdf).joint_names, loaded.start, seconds=0.1)
        else:
            write_bag(bag, joints=_joints()[0], topic="/ft_sensor/wrench")
    load_settings(vfdsl.load(TASKS_DIR.parent / task), scene)


def test_the_examples_use_every_key_and_every_kind_the_reader_accepts():
    docs = [yaml.safe_load(text) for _, text in _examples()]
    top = set().union(*docs)
    hands = [d["hand"] for d in docs if "hand" in d]
    disturbances = [x for d in docs for x in d.get("disturbances", [])]
    motions = [x for d in docs for x in d.get("motions", [])]
    metrics = [m for d in docs for m in d.get("metrics", {}).values()]
    assert top == set(scene_file.TOP_KEYS)
    assert {h["kind"] for h in hands} == set(s.HAND_KINDS)
    assert set().union(*hands) == set(scene_file.HAND_KEYS)
    assert set().union(*(d["tracker"] for d in docs if "tracker" in d)) == set(scene_file.TRACKER_KEYS)
    assert {x["kind"] for x in disturbances} == set(s.DISTURBANCE_KINDS)
    for kind in s.DISTURBANCE_KINDS:
        assert set().union(*(x for x in disturbances if x["kind"] == kind)) == set(DISTURBANCE_KEYS[kind])
    assert {x["kind"] for x in motions} == set(s.MOTION_KINDS)
    for kind in s.MOTION_KINDS:
        assert set().union(*(x for x in motions if x["kind"] == kind)) == set(scene_file.MOTION_KEYS[kind])
    assert set().union(*metrics) == set(scene_file.METRIC_KEYS)


# A valid scene for each section of lecture_follow_path (force input f, line param path, frame tip) and of
# paper_a (pose param plate): the test adds one key to the section and asks both the schema and the reader.
FOLLOW = str(TASKS_DIR / "lecture_follow_path.vf")
PAPER_A = str(TASKS_DIR / "paper_a_follow_curve.vf")
_KINDS = lambda schema, section, kind: next(x for x in schema["properties"][section]["items"]["oneOf"]  # noqa: E731
                                            if x["title"] == kind)
SECTIONS = {   # task, a valid scene, the section in it, the section's schema
    "top": (FOLLOW, {"units": "mm"}, lambda d: d, lambda sc: sc),
    "tracker": (FOLLOW, {"tracker": {"noise": 0.0002}}, lambda d: d["tracker"], lambda sc: sc["properties"]["tracker"]),
    "hand": (FOLLOW, {"hand": {"input": "f", "kind": "push", "direction": [1, 0, 0], "magnitude": 1}},
             lambda d: d["hand"], lambda sc: sc["properties"]["hand"]),
    "push_tool": (FOLLOW, {"disturbances": [{"at": 1, "kind": "push_tool", "frame": "tip", "by": [0, 0, 0]}]},
                  lambda d: d["disturbances"][0], lambda sc: _KINDS(sc, "disturbances", "push_tool")),
    "move_param": (PAPER_A, {"disturbances": [{"at": 1, "kind": "move_param", "param": "plate"}]},
                   lambda d: d["disturbances"][0], lambda sc: _KINDS(sc, "disturbances", "move_param")),
    "metric": (FOLLOW, {"metrics": {"e": {"error_of": "tip along"}}}, lambda d: d["metrics"]["e"],
               lambda sc: sc["properties"]["metrics"]["additionalProperties"]),
    "sine": (PAPER_A, {"motions": [{"param": "plate", "kind": "sine", "amplitude": [0, 0, 0.001], "frequency": 1}]},
             lambda d: d["motions"][0], lambda sc: _KINDS(sc, "motions", "sine")),
    "step": (PAPER_A, {"motions": [{"param": "plate", "kind": "step", "at": 1, "offset": [0, 0, 0.001]}]},
             lambda d: d["motions"][0], lambda sc: _KINDS(sc, "motions", "step")),
    "ramp": (PAPER_A, {"motions": [{"param": "plate", "kind": "ramp", "start": 1, "end": 2, "offset": [0, 0, 0.001]}]},
             lambda d: d["motions"][0], lambda sc: _KINDS(sc, "motions", "ramp")),
}
ALL_KEYS = sorted(set(scene_file.TOP_KEYS) | set(scene_file.HAND_KEYS) | set(scene_file.TRACKER_KEYS) | set(scene_file.METRIC_KEYS)
                  | {k for keys in scene_file.MOTION_KEYS.values() for k in keys}
                  | {k for keys in DISTURBANCE_KEYS.values() for k in keys} | {"bogus"})
REFUSED = "unknown key|does not apply"


@pytest.mark.parametrize("section", SECTIONS)
def test_the_schema_and_the_reader_accept_the_same_keys(tmp_path, section):
    """Every key (of any section, and one of none) added to a valid scene's section: a key the section's schema
    lists the reader takes (its value may still be wrong); any other key both refuse."""
    task_file, base, part, part_schema = SECTIONS[section]
    validator = _validator()
    accepted = set(part_schema(scene_schema())["properties"])
    assert part_schema(scene_schema())["additionalProperties"] is False
    task = vfdsl.load(task_file)
    scene = tmp_path / "x.sim.yaml"
    scene.write_text(yaml.safe_dump(base))
    assert not list(validator.iter_errors(base))
    load_settings(task, scene)
    for key in ALL_KEYS:
        doc = json.loads(json.dumps(base))
        if key in part(doc):
            continue
        part(doc)[key] = 1
        scene.write_text(yaml.safe_dump(doc))
        try:
            load_settings(task, scene)
            message = ""
        except VfError as err:
            message = err.message
        if key in accepted:
            assert not re.search(REFUSED, message), (section, key, message)
        else:
            assert re.search(REFUSED, message), (section, key, message)
            assert list(validator.iter_errors(doc)), (section, key)


def test_simulate_help_points_to_the_scene_documentation(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    out = capsys.readouterr().out
    assert "docs/simulate.md" in out and (DOCS / "simulate.md").is_file()
