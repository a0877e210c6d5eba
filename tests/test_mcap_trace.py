"""`vfdsl simulate --trace run.mcap` (issue 36, item 3): the trace as standard ROS 2 messages in an MCAP file, which
both `mcap` and `rosbags` read back with every documented topic, the joints and inputs equal to the CSV trace's to
float precision."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from vfdsl.cli import main

from conftest import TASKS_DIR

TELEOP = TASKS_DIR / "teleop" / "teleop_keep_out.vf"


def _run(tmp_path, task: Path, suffix: str, *extra: str) -> Path:
    out = tmp_path / f"run{suffix}"
    assert main(["simulate", str(task), "--duration", "0.3 s", "--trace", str(out), "--quiet", *extra]) == 0
    return out


@pytest.fixture(scope="module")
def paper_b(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mcap")
    task = TASKS_DIR / "paper_b_virtual_rcm.vf"
    return _run(folder, task, ".mcap", "--trials", "1"), _run(folder, task, ".csv", "--trials", "1")


def _messages(path: Path) -> dict[str, list]:
    from rosbags.highlevel import AnyReader
    found: dict[str, list] = {}
    with AnyReader([path]) as reader:
        for connection, stamp, raw in reader.messages():
            found.setdefault(connection.topic, []).append((stamp, reader.deserialize(raw, connection.msgtype),
                                                           connection.msgtype))
    return found


def test_rosbags_reads_the_joints_and_inputs_of_the_csv_trace(paper_b):
    mcap_path, csv_path = paper_b
    rows = list(csv.DictReader(csv_path.open()))
    found = _messages(mcap_path)
    joints = [c[len("q."):].rsplit("_", 1)[0] for c in rows[0] if c.startswith("q.")]
    states = found["/joint_states"]
    assert len(states) == len(rows) and states[0][2] == "sensor_msgs/msg/JointState"
    for row, (stamp, msg, _) in zip(rows, states):
        assert list(msg.name) == joints
        assert np.allclose(msg.position, [float(row[c]) for c in row if c.startswith("q.")], rtol=0, atol=1e-15)
        assert stamp == round(float(row["t_s"]) * 1e9)
    period = float(rows[1]["t_s"]) - float(rows[0]["t_s"])
    dq = [float(rows[3][c]) for c in rows[3] if c.startswith("dq.")]
    assert np.allclose(states[3][1].velocity, np.array(dq) / period, rtol=1e-12)
    wrench = [m for _, m, _ in found["/vfdsl/input/tau"]]          # paper B's input: a torque
    torque = [[float(row[f"input.tau.{a}"]) for a in ("tx_Nm", "ty_Nm", "tz_Nm")] for row in rows]
    assert np.allclose([[w.wrench.torque.x, w.wrench.torque.y, w.wrench.torque.z] for w in wrench], torque,
                       rtol=0, atol=1e-15)
    assert [m.data for _, m, _ in found["/vfdsl/status"]] == [int(row["status"]) for row in rows]


def test_mcap_lists_every_documented_topic_with_its_schema(paper_b):
    from mcap.reader import make_reader
    with paper_b[0].open("rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert {"/joint_states": "sensor_msgs/msg/JointState", "/tf": "tf2_msgs/msg/TFMessage",
            "/vfdsl/input/tau": "geometry_msgs/msg/WrenchStamped", "/vfdsl/status": "std_msgs/msg/Int32",
            "/vfdsl/violations": "std_msgs/msg/String"}.items() <= topics.items()
    assert any(t.startswith("/vfdsl/metric/") for t in topics)
    assert all(summary.schemas[c.schema_id].encoding == "ros2msg" and c.message_encoding == "cdr"
               for c in summary.channels.values())
    counts = {summary.channels[k].topic: n for k, n in summary.statistics.channel_message_counts.items()}
    assert topics["/vfdsl/fixtures"] == "visualization_msgs/msg/MarkerArray" and counts.pop("/vfdsl/fixtures") >= 1
    assert set(counts.values()) == {30}               # one message per tick (0.3 s at 10 ms) on every other topic


def test_tf_carries_each_task_frame_as_pinocchio_places_it(paper_b):
    from scipy.spatial.transform import Rotation
    import vfdsl
    from vfdsl.compiler.geometry import homogeneous
    from vfdsl.kinematics.robot import Robot
    task = vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")
    robot = Robot.load(task.robots[0].urdf)
    found = _messages(paper_b[0])
    q = found["/joint_states"][20][1].position
    tf = found["/tf"][20][1]
    for frame, transform in zip(task.frames, tf.transforms):
        p, R = robot.frame_pose(q, frame.link, homogeneous(frame.offset, frame.rpy))
        t, r = transform.transform.translation, transform.transform.rotation
        assert transform.child_frame_id == frame.name and transform.header.frame_id == "world"
        assert np.allclose([t.x, t.y, t.z], p, atol=1e-15)
        assert np.allclose(Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix(), R, atol=1e-12)


def test_a_teleoperated_run_writes_the_master_the_clutch_the_haptic_force_and_the_phase(tmp_path):
    found = _messages(_run(tmp_path, TELEOP, ".mcap"))
    types = {topic: messages[0][2] for topic, messages in found.items()}
    assert types["/vfdsl/input/master"] == "geometry_msgs/msg/PoseStamped"
    assert types["/vfdsl/input/clutch"] == "std_msgs/msg/Bool"
    assert types["/vfdsl/haptic"] == "geometry_msgs/msg/WrenchStamped"
    assert {m.data for _, m, _ in found["/vfdsl/phase"]} == {"following"}
    master = found["/vfdsl/input/master"][-1][1].pose.position
    assert master.z < -1e-3                                  # the operator's path moves the master down


def test_several_trials_go_under_their_own_namespace(tmp_path):
    found = _messages(_run(tmp_path, TASKS_DIR / "paper_b_virtual_rcm.vf", ".mcap", "--trials", "2"))
    assert {"/trial_0/joint_states", "/trial_1/joint_states"} <= set(found)
    assert "/joint_states" not in found


def test_view_replays_an_mcap_trace_as_it_replays_the_csv(paper_b):
    """vfdsl view --replay run.mcap reads the same times, joints, status and error as from the run's CSV trace."""
    import vfdsl
    from vfdsl.kinematics.robot import Robot
    from vfdsl.view import replay
    task = vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")
    joints = Robot.load(task.robots[0].urdf).joint_names
    from_mcap = replay.read(paper_b[0], joints, task.scene.period)
    from_csv = replay.read(paper_b[1], joints, task.scene.period)
    assert np.allclose(from_mcap.t, from_csv.t, atol=1e-9)
    assert np.array_equal(from_mcap.q, from_csv.q)
    assert np.array_equal(from_mcap.status, from_csv.status)
    assert from_mcap.error_name == from_csv.error_name
    assert np.allclose(from_mcap.error, from_csv.error, equal_nan=True, rtol=0, atol=0)


def test_view_replays_one_trial_of_several_and_refuses_what_is_not_a_trace(tmp_path):
    import vfdsl
    from vfdsl.errors import VfError
    from vfdsl.kinematics.robot import Robot
    from vfdsl.view import replay
    task = vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")
    joints = Robot.load(task.robots[0].urdf).joint_names
    run = _run(tmp_path, TASKS_DIR / "paper_b_virtual_rcm.vf", ".mcap", "--trials", "2")
    assert replay.read(run, joints, trial="1").trial == "1"
    with pytest.raises(VfError, match="no trial 7"):
        replay.read(run, joints, trial="7")
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    with pytest.raises(VfError, match="not a readable MCAP trace"):
        replay.read(junk, joints)


def test_the_params_a_motion_moves_are_written_each_tick(tmp_path):
    """breathing_vessel's vessel curve breathes (a motion): /vfdsl/param/vessel carries its points at each tick, equal
    to the CSV trace's param columns, and vfdsl view --replay reads them from either file alike."""
    task = TASKS_DIR / "breathing_vessel.vf"
    found = _messages(_run(tmp_path, task, ".mcap", "--trials", "1"))
    rows = list(csv.DictReader(_run(tmp_path, task, ".csv", "--trials", "1").open()))
    columns = [c for c in rows[0] if c.startswith("param.vessel.")]
    messages = found["/vfdsl/param/vessel"]
    assert messages[0][2] == "std_msgs/msg/Float64MultiArray" and len(messages) == len(rows)
    values = np.array([m.data for _, m, _ in messages])
    assert np.array_equal(values, [[float(row[c]) for c in columns] for row in rows])
    assert np.ptp(values, axis=0).max() > 1e-5                 # it moved
    import vfdsl
    from vfdsl.kinematics.robot import Robot
    from vfdsl.view import replay
    loaded = vfdsl.load(task)
    joints, sizes = Robot.load(loaded.robots[0].urdf).joint_names, {"vessel": len(columns)}
    played = [replay.read(tmp_path / f"run{s}", joints, loaded.scene.period, None, sizes) for s in (".mcap", ".csv")]
    assert np.array_equal(played[0].params["vessel"], played[1].params["vessel"])


def _marker_states(messages) -> list[tuple[int, dict]]:
    """The markers shown after each /vfdsl/fixtures message: (stamp, {(ns, id): marker}), ADD replacing and DELETE
    removing a marker of the same namespace and id, as Foxglove and RViz apply them."""
    shown, states = {}, []
    for stamp, array, msgtype in messages:
        assert msgtype == "visualization_msgs/msg/MarkerArray"
        for m in array.markers:
            assert m.header.frame_id == "world" and m.lifetime.sec == 0 and m.lifetime.nanosec == 0
            assert (m.pose.orientation.w, m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z) == (1, 0, 0, 0)
            if m.action == m.DELETE:
                shown.pop((m.ns, m.id))
            else:
                shown[(m.ns, m.id)] = m
        states.append((stamp, dict(shown)))
    return states


def _points(marker) -> np.ndarray:
    return np.array([[p.x, p.y, p.z] for p in marker.points]).reshape(-1, 3)


def test_the_markers_draw_the_mesh_where_the_task_puts_it_and_the_tool_where_tf_puts_it(tmp_path):
    """sinus_channel: the channel (inside_mesh, a wire frame) is the STL's own edges in metres, written once; the
    tool's shaft segment is the TF's tip and shaft origins, within MARKER_MOVE at every tick the markers are drawn
    (MARKER_RATE) and exactly where it was written; each fixture with geometry has its label."""
    import trimesh
    from vfdsl.sim.markers import MARKER_MOVE, MARKER_RATE
    found = _messages(_run(tmp_path, TASKS_DIR / "sinus_channel.vf", ".mcap", "--trials", "1", "--duration", "1 s"))
    states = _marker_states(found["/vfdsl/fixtures"])
    first = states[0][1]
    by_name = {ns: m for (ns, _), m in first.items()}
    assert {ns.split("/")[0] for ns in by_name} == {"c0_inside_mesh_tip"}   # speeds and joint bounds draw nothing
    assert set(by_name) == {f"c0_inside_mesh_tip/{name}" for name in ("mesh", "shaft", "capsule", "clearance", "label")}
    stl = trimesh.load(TASKS_DIR / "anatomy" / "channel.stl")

    def edges(pairs):
        return {tuple(sorted((tuple(np.round(a, 9)), tuple(np.round(b, 9))))) for a, b in pairs}

    wire = by_name["c0_inside_mesh_tip/mesh"]
    assert wire.type == wire.LINE_LIST
    assert edges(_points(wire).reshape(-1, 2, 3)) == edges(stl.vertices[stl.edges_unique] * 1e-3)
    writes = sum(any(x.ns == wire.ns for x in array.markers) for _, array, _ in found["/vfdsl/fixtures"])
    assert writes == 1                                             # the channel does not move: written once
    label = by_name["c0_inside_mesh_tip/label"]
    assert label.type == label.TEXT_VIEW_FACING and label.text.startswith("inside_mesh(tip) sinus_channel.vf:")
    tf = {stamp: {t.child_frame_id: [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z]
                  for t in msg.transforms} for stamp, msg, _ in found["/tf"]}
    stamps = sorted(tf)
    every = round(1 / (MARKER_RATE * 0.01))                        # sinus_channel's period: 10 ms
    drawn = stamps[::every] + stamps[-1:]
    assert len(drawn) == 10 + 1                                    # 0, 0.1, ... 0.9 s and the last tick
    written = {stamp for stamp, array, _ in found["/vfdsl/fixtures"]
               for m in array.markers if m.ns == "c0_inside_mesh_tip/shaft"}
    assert len(written) > 3                                        # the tool moved: its segment was written again
    k = 0
    for stamp in drawn:
        while k + 1 < len(states) and states[k + 1][0] <= stamp:
            k += 1
        segment = next(_points(m) for m in states[k][1].values() if m.ns == "c0_inside_mesh_tip/shaft")
        ends = np.array([tf[stamp]["tip"], tf[stamp]["shaft"]])
        gap = np.abs(segment - ends).max()
        assert gap <= MARKER_MOVE, (stamp, gap)
        if stamp in written:
            assert gap < 1e-12


def test_the_markers_follow_a_param_a_motion_moves(tmp_path):
    """breathing_vessel: the vessel's knots (a SPHERE_LIST) are the points /vfdsl/param/vessel carries, exactly at
    every marker write, and the written ones move with it."""
    found = _messages(_run(tmp_path, TASKS_DIR / "breathing_vessel.vf", ".mcap", "--trials", "1", "--duration", "1 s"))
    params = {stamp: np.asarray(msg.data).reshape(-1, 3) for stamp, msg, _ in found["/vfdsl/param/vessel"]}
    knots = [(stamp, _points(m)) for stamp, array, _ in found["/vfdsl/fixtures"] for m in array.markers
             if m.ns == "c0_follows_tip/points" and m.type == m.SPHERE_LIST]
    assert len(knots) >= 5
    for stamp, points in knots:
        assert np.allclose(points, params[stamp], rtol=0, atol=1e-15)
    assert np.ptp([p for _, p in knots], axis=0).max() > 1e-5


def test_paper_b_draws_its_pivot_at_the_pivot_param(paper_b):
    """The pivot's 4x4 polytope (a cube, eps = 1 um from the pivot along each axis) and its guaranteed ball (radius
    sqrt 3 um, the cube's circumradius) are centred on the pivot param, as /vfdsl/param/pivot gives it."""
    found = _messages(paper_b[0])
    pivot = np.asarray(found["/vfdsl/param/pivot"][0][1].data)
    shown = {m.ns: m for m in _marker_states(found["/vfdsl/fixtures"])[0][1].values()}
    cube, bound = _points(shown["c0_stays_at_tip/polytope"]), _points(shown["c0_stays_at_tip/bound"])
    assert shown["c0_stays_at_tip/polytope"].type == shown["c0_stays_at_tip/polytope"].TRIANGLE_LIST
    assert len(cube) == 12 * 3                                      # 12 triangles
    assert np.allclose(np.abs(cube - pivot), 1e-6, rtol=0, atol=1e-15)
    assert np.allclose(np.linalg.norm(bound - pivot, axis=1), np.sqrt(3) * 1e-6, rtol=1e-9)


def _joint_states(path, messages):
    """An MCAP bag of /joint_states: each of ``messages`` a (names, positions), 10 ms apart."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for k, (names, positions) in enumerate(messages):
            header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=100, nanosec=k * 10_000_000),
                                              frame_id="")
            msg = T["sensor_msgs/msg/JointState"](header=header, name=list(names), position=np.array(positions, float),
                                                  velocity=np.zeros(0), effort=np.zeros(0))
            writer.write(connection, 100_000_000_000 + k * 10_000_000,
                         store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    return next(path.glob("*.mcap"))


def test_view_reads_each_joint_state_by_its_own_names_and_refuses_a_broken_one(tmp_path):
    """A lab's /joint_states whose driver changes the joints' order, a NaN joint (a refused tick), an empty topic, a
    message lacking a joint or a position: read by each message's names, the NaN one dropped, the others refused with
    the file and the message (before: the first message's order for all, NaN passed on, IndexError tracebacks)."""
    from vfdsl.errors import VfError
    from vfdsl.view import replay
    names = ["a", "b", "c"]
    q = [0.1, 0.2, 0.3]
    trace = replay.read(_joint_states(tmp_path / "order", [(names, q), (names[::-1], q[::-1]),
                                                            (names, [np.nan, 0.2, 0.3]), (names, q)]), names)
    assert np.array_equal(trace.q, [q, q, q]) and np.allclose(trace.t, [0.0, 0.01, 0.03])
    for name, messages, message in (
            ("empty", [], "its /joint_states topic has no message"),
            ("lacks", [(names, q), (names[:2], q[:2])], "joint state 1 has no joint 'c' of the task's robot"),
            ("short", [(names, q[:2])], "joint state 0 names 3 joints but has 2 positions")):
        with pytest.raises(VfError, match=message):
            replay.read(_joint_states(tmp_path / name, messages), names)
