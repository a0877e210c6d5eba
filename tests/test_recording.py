"""A lab's recording drives `vfdsl simulate` (issue 36, item 1 and the closed loop of item 2): a bag written here with
rosbags (a WrenchStamped at 1 kHz with 5 % jitter, a JointState) maps to paper B's torque input and start; each tick
reads the latest message; a bad bag is refused with the bag, the topic and the message's index, exit 2."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.cli import main

from conftest import TASKS_DIR

PAPER_B = TASKS_DIR / "paper_b_virtual_rcm.vf"


def write_bag(path: Path, *, rate=1000.0, seconds=1.0, jitter=0.05, torque_type="geometry_msgs/msg/WrenchStamped",
              joints=None, shuffle_at=None, seed=0, storage="mcap", topic="/ft/wrench", frame_id="world"):
    """A rosbag2 (MCAP or sqlite3 storage) with ``topic`` (the torque a slow sine, N m, in ``frame_id``) and
    /joint_states (one message: ``joints`` {name: position}). Returns the wrench messages' (stamps, torques)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    rng = np.random.default_rng(seed)
    n = int(rate * seconds)
    stamps = np.cumsum(np.full(n, 1 / rate) * (1 + jitter * rng.uniform(-1, 1, n))) + 100.0
    recorded = stamps.copy()                                    # when the recorder got each message: in order
    if shuffle_at is not None:                                  # the sensor's own stamps, two of them swapped
        stamps[shuffle_at], stamps[shuffle_at - 1] = stamps[shuffle_at - 1], stamps[shuffle_at]
    torques = np.column_stack([0.02 * np.sin(2 * np.pi * 0.5 * stamps), 0.01 * np.cos(stamps), 0.005 + 0 * stamps])

    def header(t):
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=int(t), nanosec=int(round(
            (t - int(t)) * 1e9)) % 1_000_000_000), frame_id=frame_id)

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        wrench = writer.add_connection(topic, torque_type, typestore=store)
        for t, at, tau in zip(stamps, recorded, torques):
            if torque_type.endswith("WrenchStamped"):
                msg = T[torque_type](header=header(t), wrench=T["geometry_msgs/msg/Wrench"](
                    force=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                    torque=T["geometry_msgs/msg/Vector3"](x=float(tau[0]), y=float(tau[1]), z=float(tau[2]))))
            else:
                msg = T[torque_type](header=header(t), twist=T["geometry_msgs/msg/Twist"](
                    linear=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                    angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)))
            writer.write(wrench, int(at * 1e9), store.serialize_cdr(msg, torque_type))
        if joints is not None:
            states = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
            msg = T["sensor_msgs/msg/JointState"](header=header(stamps[0]), name=list(joints),
                                                  position=np.array(list(joints.values()), dtype=float),
                                                  velocity=np.zeros(0), effort=np.zeros(0))
            writer.write(states, int(stamps[0] * 1e9), store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    return stamps - stamps[0], torques


def _joints():
    from vfdsl.kinematics.robot import Robot
    task = vfdsl.load(PAPER_B)
    robot = Robot.load(task.robots[0].urdf)
    start = np.array(task.start, dtype=float)
    start[0] += 1e-4                                     # 0.1 mm from the scene's start: read from the bag
    return dict(zip(robot.joint_names, start.tolist())), start


def _scene(tmp_path, body: str) -> Path:
    scene = tmp_path / "run.sim.yaml"
    scene.write_text("units: mm, deg\nduration: 0.8 s\nperiod: 10 ms\ntrials: 1\n" + body)
    return scene


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_bag_drives_the_simulation_tick_by_tick(tmp_path, storage):
    """Paper B at its 10 ms period from a 1 kHz recording with 5 % jitter: at tick k (t = k x 10 ms) the torque is the
    latest message stamped at or before t, exactly; the robot starts where the bag's JointState says."""
    joints, start = _joints()
    stamps, torques = write_bag(tmp_path / "lab", joints=joints, storage=storage)
    scene = _scene(tmp_path, "recording:\n  bag: lab\n  inputs: {tau: /ft/wrench}\n  start: /joint_states\n")
    out = tmp_path / "trace.csv"
    assert main(["simulate", str(PAPER_B), "--scene", str(scene), "--trace", str(out), "--quiet"]) == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 80
    for row in rows:
        t = float(row["t_s"])
        k = np.searchsorted(stamps, t + 1e-12, side="right") - 1
        got = [float(row[f"input.tau.{a}_Nm"]) for a in ("tx", "ty", "tz")]
        assert np.array_equal(got, torques[k])
    q0 = [float(rows[0][c]) for c in rows[0] if c.startswith("q.")]
    assert np.allclose(q0, start, atol=0, rtol=0)


def test_the_heading_reports_the_recording_and_its_jitter(tmp_path, capsys):
    write_bag(tmp_path / "lab", jitter=0.05)
    scene = _scene(tmp_path, "recording:\n  bag: lab\n  inputs: {tau: /ft/wrench}\n")
    assert main(["simulate", str(PAPER_B), "--scene", str(scene)]) == 0
    out = capsys.readouterr().out
    import re
    found = re.search(r"recorded inputs: lab: 'tau' <- /ft/wrench \(1000 messages over 1 s, ([0-9.]+) Hz, period "
                      r"jitter ([0-9.]+) ms RMS, ([0-9.]+) ms at most\); each tick \(10 ms\) reads the latest message",
                      out)
    assert found, out
    rate, rms, worst = map(float, found.groups())
    assert 990 < rate < 1010 and 0.01 < rms < 0.05 and 0.03 < worst <= 0.1     # 5 % of 1 ms: up to 0.1 ms


@pytest.mark.parametrize("change, message", [
    ({"recording": "  bag: lab\n  inputs: {tau: /ft/wrenches}\n"}, "bag lab has no topic /ft/wrenches"),
    ({"bag": {"torque_type": "geometry_msgs/msg/TwistStamped"}},
     "topic /ft/wrench: geometry_msgs/msg/TwistStamped messages, but input 'tau' reads geometry_msgs/msg/WrenchStamped"),
    ({"bag": {"shuffle_at": 250}}, "topic /ft/wrench: message 250 is stamped"),
    ({"bag": {"joints": {"shoulder": 0.0}}, "recording": "  bag: lab\n  start: /joint_states\n"},
     "names joint 'shoulder', which the robot lacks"),
    ({"recording": "  bag: elsewhere\n  inputs: {tau: /ft/wrench}\n"}, "no bag at"),
    ({"recording": "  bag: lab\n  inputs: {force: /ft/wrench}\n"}, "maps 'force', which task"),
    ({"recording": "  bag: lab\n  mode: open\n  inputs: {tau: /ft/wrench}\n"}, "the open mode replays recorded joints"),
    ({"recording": "  bag: lab\n  mode: sideways\n  inputs: {tau: /ft/wrench}\n"}, "unknown recording mode 'sideways'"),
    ({"recording": "  bag: lab\n  joints: /joint_states\n  inputs: {tau: /ft/wrench}\n"},
     "recorded joints are replayed in the open mode only"),
])
def test_a_bad_bag_is_refused_with_the_bag_the_topic_and_the_index(tmp_path, capsys, change, message):
    write_bag(tmp_path / "lab", **change.get("bag", {}))
    body = change.get("recording", "  bag: lab\n  inputs: {tau: /ft/wrench}\n")
    scene = _scene(tmp_path, "recording:\n" + body)
    assert main(["simulate", str(PAPER_B), "--scene", str(scene)]) == 2
    err = capsys.readouterr().err
    assert message in err and "run.sim.yaml:" in err and "Traceback" not in err


def _write_topics(path: Path, topics: list):
    """A rosbag2 (MCAP) holding, for each (topic, msgtype, messages, sec) of ``topics``, its messages (built by each
    callable from the typestore's types) stamped ``sec`` + 1 ms apart."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for topic, msgtype, messages, sec in topics:
            connection = writer.add_connection(topic, msgtype, typestore=store)
            for k, build in enumerate(messages):
                header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
                    sec=sec, nanosec=k * 1_000_000), frame_id="")
                writer.write(connection, sec * 1_000_000_000 + k * 1_000_000,
                             store.serialize_cdr(build(T, header), msgtype))


def _wrench(torque, stamped=True):
    def build(T, header):
        v = T["geometry_msgs/msg/Vector3"]
        if not stamped:
            header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="")
        return T["geometry_msgs/msg/WrenchStamped"](header=header, wrench=T["geometry_msgs/msg/Wrench"](
            force=v(x=0.0, y=0.0, z=0.0), torque=v(x=torque[0], y=torque[1], z=torque[2])))
    return build


def _joint_state(names, positions):
    def build(T, header):
        return T["sensor_msgs/msg/JointState"](header=header, name=list(names), position=np.array(positions, float),
                                               velocity=np.zeros(0), effort=np.zeros(0))
    return build


def _bad_message_cases():
    joints, _ = _joints()
    names, q = list(joints), list(joints.values())
    torque, state = ("/ft/wrench", "geometry_msgs/msg/WrenchStamped"), ("/joint_states", "sensor_msgs/msg/JointState")
    return [
        (torque, [], "topic /ft/wrench: no message"),
        (state, [], "topic /joint_states: no message"),
        (torque, [_wrench([0.0, 0.0, 0.005])] * 3 + [_wrench([0.0, float("nan"), 0.005])],
         "topic /ft/wrench, message 3 holds NaN or inf in its torque: [0.0, nan, 0.005]"),
        (torque, [_wrench([float("inf"), 0.0, 0.0])], "topic /ft/wrench, message 0 holds NaN or inf in its torque"),
        (state, [_joint_state(names, [float("nan")] + q[1:])],
         "topic /joint_states, message 0 holds NaN or inf in its positions"),
        (state, [_joint_state(names, q + [0.0])], "topic /joint_states, message 0 names 7 joints but has 8 positions"),
        (state, [_joint_state(names + names[:1], q + [0.5])],
         f"topic /joint_states, message 0 names joint '{names[0]}' twice"),
        (torque, [_wrench([0.0, 0.0, 0.005], stamped=False)] + [_wrench([0.0, 0.0, 0.005])] * 3,
         "topic /ft/wrench: message 0 has a zero header stamp and message 1 has one"),
        (state, [_joint_state(names, [q[0], 57.3 * q[1]] + q[2:])],
         "topic /joint_states, message 0 puts joint 'y' at -0.253969, far outside its limits [-0.06, 0.06]"),
    ]


@pytest.mark.parametrize("case", range(9))
def test_a_message_that_cannot_drive_the_run_is_refused_before_it_starts(tmp_path, capsys, case):
    """An empty topic, NaN or inf in a message, a JointState with a joint twice, more positions than names or a joint
    far outside its limits (degrees as radians): refused when the bag is read, naming the bag, the topic and the
    message (not a traceback, not a refusal of some tick in the middle of the run without the bag)."""
    (topic, msgtype), messages, message = _bad_message_cases()[case]
    _write_topics(tmp_path / "lab", [(topic, msgtype, messages, 100)])
    mapping = "  inputs: {tau: /ft/wrench}\n" if topic == "/ft/wrench" else "  start: /joint_states\n"
    scene = _scene(tmp_path, "recording:\n  bag: lab\n" + mapping)
    assert main(["simulate", str(PAPER_B), "--scene", str(scene), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"bag lab, {message}" in err and "run.sim.yaml:" in err and "Traceback" not in err, err


def test_an_input_recorded_after_the_run_by_another_clock_is_warned_of(tmp_path, capsys):
    """The start's JointState stamped by the robot's clock (100 s), the torque by the sensor's (wall time): time 0 is
    the earliest stamp, so every torque message comes 1.7e9 s after the run's end and the torque reads zero the whole
    run. The run says so (it said nothing)."""
    joints, _ = _joints()
    _write_topics(tmp_path / "lab", [("/joint_states", "sensor_msgs/msg/JointState",
                                      [_joint_state(list(joints), list(joints.values()))], 100),
                                     ("/ft/wrench", "geometry_msgs/msg/WrenchStamped",
                                      [_wrench([0.0, 0.0, 0.05])] * 20, 1_700_000_000)])
    scene = _scene(tmp_path, "recording:\n  bag: lab\n  inputs: {tau: /ft/wrench}\n  start: /joint_states\n")
    assert main(["simulate", str(PAPER_B), "--scene", str(scene), "--quiet", "--duration", "0.1s"]) == 0
    err = capsys.readouterr().err
    said = ("warning: input 'tau''s recording (/ft/wrench, its first message stamped 1.7e+09 s after the recording's "
            "time 0")
    assert "run.sim.yaml:" in err and said in err and "starts after the run's 0.1 s" in err, err


def test_the_open_mode_replays_the_recorded_joints_and_records_what_the_fixture_would_command(tmp_path):
    """A closed loop of paper B recorded as a bag (its joints at each 10 ms tick, the torque at 1 kHz), replayed open
    loop: the trace's q is the recorded joints, and its dq what Controller.step commands there with the recorded
    torque (a controller of the same task, stepped on the same states), to 1e-15."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    from vfdsl.kinematics.robot import Robot
    stamps, torques = write_bag(tmp_path / "torque", seconds=0.6)
    task = vfdsl.load(PAPER_B)
    robot = Robot.load(task.robots[0].urdf)
    ctrl = vfdsl.compile(task)
    q = np.array(task.start, dtype=float)
    joints = []
    for k in range(50):                                    # a run of the robot, recorded at its 10 ms ticks
        t = k * 0.01
        tau = torques[np.searchsorted(stamps, t + 1e-12, side="right") - 1]
        joints.append(q.copy())
        q = q + 1.3 * ctrl.step(q, {"tau": tau})          # a real robot: not exactly what was commanded
    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    # one bag: the torque messages again, and the joints at the ticks (stamped like the torque's first message)
    with Writer(tmp_path / "lab", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        from rosbags.highlevel import AnyReader
        with AnyReader([tmp_path / "torque"]) as reader:
            wrench = writer.add_connection("/ft/wrench", "geometry_msgs/msg/WrenchStamped", typestore=store)
            for n, (connection, stamp, raw) in enumerate(reader.messages()):
                if n == 0:
                    stamp0 = reader.deserialize(raw, connection.msgtype).header.stamp     # the recording's time 0
                writer.write(wrench, stamp, raw)
        states = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for k, position in enumerate(joints):           # joint state k stamped 2 us before tick k (tick 0: at 0)
            ns = stamp0.sec * 1_000_000_000 + stamp0.nanosec + k * 10_000_000 - 2_000 * (k > 0)
            sec, nanosec = divmod(ns, 1_000_000_000)
            t = ns * 1e-9
            msg = T["sensor_msgs/msg/JointState"](header=T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=""),
                name=list(robot.joint_names), position=position, velocity=np.zeros(0), effort=np.zeros(0))
            writer.write(states, int(t * 1e9), store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    scene = _scene(tmp_path, "duration: 0.45 s\nrecording:\n  bag: lab\n  mode: open\n  inputs: {tau: /ft/wrench}\n"
                             "  joints: /joint_states\n")
    scene.write_text(scene.read_text().replace("duration: 0.8 s\n", ""))
    out = tmp_path / "trace.csv"
    assert main(["simulate", str(PAPER_B), "--scene", str(scene), "--trace", str(out), "--quiet"]) == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 45
    check = vfdsl.compile(task)
    for k, row in enumerate(rows):
        q_row = np.array([float(row[c]) for c in row if c.startswith("q.")])
        tau = np.array([float(row[f"input.tau.{a}_Nm"]) for a in ("tx", "ty", "tz")])
        assert np.array_equal(q_row, joints[k])
        dq = check.step(q_row, {"tau": tau})
        assert np.allclose([float(row[c]) for c in row if c.startswith("dq.")], dq, rtol=0, atol=1e-15)


TELEOP_LINE = TASKS_DIR / "teleop" / "teleop_guide_line.vf"
REFERENCE_STEP = np.array([0.2, 0.1, 0.02, 0.0, 0.0, 0.0])     # yaw, pitch (rad), insertion (m): tip +x, -y, -z


def _write_joint_bag(path: Path, names, start, *, rate=1000.0, seconds=1.0, jitter=0.05, seed=1,
                     topic="/joint_states", drop_at=None):
    """A rosbag2 (MCAP) of sensor_msgs/JointState at ``rate`` with jitter: the joints go smoothly from ``start`` to
    ``start + REFERENCE_STEP`` over ``seconds``. ``drop_at``: that message lacks its last joint. Returns the stamps
    (s, from the first) and the joints at each."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    rng = np.random.default_rng(seed)
    n = int(rate * seconds)
    stamps = 50.0 + np.cumsum(np.full(n, 1 / rate) * (1 + jitter * rng.uniform(-1, 1, n)))
    s = np.clip((stamps - stamps[0]) / seconds, 0, 1)
    joints = np.asarray(start) + (3 * s ** 2 - 2 * s ** 3)[:, None] * REFERENCE_STEP
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        states = writer.add_connection(topic, "sensor_msgs/msg/JointState", typestore=store)
        for k, (t, q) in enumerate(zip(stamps, joints)):
            sec, nanosec = divmod(int(round(t * 1e9)), 1_000_000_000)
            keep = len(names) - 1 if k == drop_at else len(names)
            msg = T["sensor_msgs/msg/JointState"](header=T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=""),
                name=list(names)[:keep], position=q[:keep], velocity=np.zeros(0), effort=np.zeros(0))
            writer.write(states, int(round(t * 1e9)), store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    return stamps - stamps[0], joints


def test_recorded_joints_are_a_reference_for_a_pose_input(tmp_path):
    """teleop_guide_line driven by a recorded motion of its own robot (1 kHz, 5 % jitter): the master input at each
    tick is the tip's pose at the latest recorded joints (Pinocchio), and the slave follows it as a master's: scaled
    0.4 along the planned line, held within the line's 0.5 mm octagon across it where the recorded motion left it."""
    from scipy.spatial.transform import Rotation
    from vfdsl.compiler.geometry import homogeneous
    from vfdsl.kinematics.robot import Robot
    task = vfdsl.load(TELEOP_LINE)
    robot = Robot.load(task.robots[0].urdf)
    frame = task.frame("tip")
    stamps, joints = _write_joint_bag(tmp_path / "lab", robot.joint_names, task.start)
    scene = tmp_path / "run.sim.yaml"
    scene.write_text("units: mm, deg\nduration: 1.6 s\nperiod: 1 ms\ntrials: 1\nrecording:\n  bag: lab\n"
                     "  inputs:\n    master: {topic: /joint_states, frame: tip}\n  start: /joint_states\n")
    out = tmp_path / "trace.csv"
    assert main(["simulate", str(TELEOP_LINE), "--scene", str(scene), "--trace", str(out), "--quiet"]) == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 1600
    columns = [f"input.master.{c}" for c in ("px_m", "py_m", "pz_m", "roll_rad", "pitch_rad", "yaw_rad")]
    offset = homogeneous(frame.offset, frame.rpy)
    for row in rows[::7]:
        k = np.searchsorted(stamps, float(row["t_s"]) + 1e-12, side="right") - 1
        p, R = robot.frame_pose(joints[k], frame.link, offset)
        master = np.array([float(row[c]) for c in columns])
        assert np.allclose(master[:3], p, rtol=0, atol=1e-15)
        assert np.allclose(Rotation.from_euler("xyz", master[3:]).as_matrix(), R, rtol=0, atol=1e-12)
    q0 = np.array([float(rows[0][c]) for c in rows[0] if c.startswith("q.")])
    assert np.array_equal(q0, joints[0])
    line = np.array([1.0, 0.0, -1.0]) / np.sqrt(2)
    p_start, _ = robot.frame_pose(joints[0], frame.link, offset)
    p_master, _ = robot.frame_pose(joints[-1], frame.link, offset)
    q_end = np.array([float(rows[-1][c]) for c in rows[-1] if c.startswith("q.")])
    p_tip, _ = robot.frame_pose(q_end, frame.link, offset)
    moved, asked = p_tip - p_start, 0.4 * (p_master - p_start)
    assert np.linalg.norm(asked - (asked @ line) * line) > 2e-3             # the recording leaves the line by 2 mm+
    assert abs(moved @ line - asked @ line) < 1e-5                          # along it: the scaled recording
    across = np.linalg.norm(moved - (moved @ line) * line)                  # across it: the fixture holds the tip,
    assert across <= 0.5e-3 / np.cos(np.pi / 8) + 1e-9                       # within its octagon (resolution 8)


@pytest.mark.parametrize("mapping, message", [
    ("master: {topic: /joint_states, frame: tool}", "unknown frame 'tool'"),
    ("master: {topic: /joint_states}", "sensor_msgs/msg/JointState messages, but input 'master' reads "
                                       "geometry_msgs/msg/PoseStamped"),
    ("master: {topic: /joint_states, frame: tip, unit: mm}", "a reference from recorded joints is the frame's pose in "
                                                             "the world, in SI: drop `unit`"),
    ("clutch: {topic: /joint_states, frame: tip}", "input 'clutch' is a button"),
    ("master: /joint_states", "sensor_msgs/msg/JointState messages, but input 'master' reads "
                              "geometry_msgs/msg/PoseStamped"),
    ("master: {topic: /joint_states, frame: tip}", "message 40 has no position of joint 'outer_wrist_yaw'"),
])
def test_a_bad_reference_is_refused_at_its_line(tmp_path, capsys, mapping, message):
    from vfdsl.kinematics.robot import Robot
    task = vfdsl.load(TELEOP_LINE)
    _write_joint_bag(tmp_path / "lab", Robot.load(task.robots[0].urdf).joint_names, task.start, seconds=0.1,
                     drop_at=40)
    scene = tmp_path / "run.sim.yaml"
    scene.write_text(f"units: mm, deg\nduration: 0.1 s\nrecording:\n  bag: lab\n  inputs:\n    {mapping}\n")
    assert main(["simulate", str(TELEOP_LINE), "--scene", str(scene)]) == 2
    err = capsys.readouterr().err
    assert message in err and "run.sim.yaml:" in err and "Traceback" not in err


def test_a_sensor_on_the_tool_in_its_own_units_is_turned_into_the_world(tmp_path):
    """Paper B's torque recorded in N mm, in the tool's frame (a sensor on the tool): at each tick the input is the
    latest message x 1e-3, turned by the tip's rotation at that tick's joints (Pinocchio), to 1e-15 N m."""
    from vfdsl.compiler.geometry import homogeneous
    from vfdsl.kinematics.robot import Robot
    stamps, torques = write_bag(tmp_path / "lab")               # the numbers, now read as N mm
    scene = _scene(tmp_path, "recording:\n  bag: lab\n  inputs:\n    tau: {topic: /ft/wrench, unit: Nmm, in: tip}\n")
    out = tmp_path / "trace.csv"
    assert main(["simulate", str(PAPER_B), "--scene", str(scene), "--trace", str(out), "--quiet"]) == 0
    task = vfdsl.load(PAPER_B)
    robot, tip = Robot.load(task.robots[0].urdf), task.frame("tip")
    rows = list(csv.DictReader(out.open()))
    turned = 0.0
    for row in rows:
        k = np.searchsorted(stamps, float(row["t_s"]) + 1e-12, side="right") - 1
        q = np.array([float(row[c]) for c in row if c.startswith("q.")])
        R = robot.frame_pose(q, tip.link, homogeneous(tip.offset, tip.rpy))[1]
        got = np.array([float(row[f"input.tau.{a}_Nm"]) for a in ("tx", "ty", "tz")])
        assert np.allclose(got, R @ (torques[k] * 1e-3), rtol=0, atol=1e-15)
        turned = max(turned, float(np.abs(got - torques[k] * 1e-3).max()))
    assert turned > 1e-6                                          # the tool turned: the frame mattered


def test_a_wrench_in_a_sensor_frame_is_not_taken_as_the_worlds(tmp_path, capsys):
    """A WrenchStamped whose header names the sensor's frame ('ft'), mapped without `in:`: its vectors would be read
    as the world's axes, a torque about the sensor's x pushing about the world's. Refused when the bag is read,
    naming bag, topic, message and frame; `in: tip` (the sensor on the tool) or `in: world` (its axes are the world's)
    says which frame it is, and runs. (It ran silently with the sensor's axes as the world's.)"""
    write_bag(tmp_path / "lab", frame_id="ft")
    refused = _scene(tmp_path, "recording:\n  bag: lab\n  inputs:\n    tau: /ft/wrench\n")
    assert main(["simulate", str(PAPER_B), "--scene", str(refused), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert ("bag lab, topic /ft/wrench, message 0 is expressed in frame 'ft' (its header's frame_id), but input 'tau' "
            "is read in the world ('base', the robot's base)") in err and "in: FRAME" in err, err
    assert "Traceback" not in err
    for stated in ("tip", "world"):
        scene = _scene(tmp_path, f"recording:\n  bag: lab\n  inputs:\n    tau: {{topic: /ft/wrench, in: {stated}}}\n")
        assert main(["simulate", str(PAPER_B), "--scene", str(scene), "--quiet"]) == 0, capsys.readouterr().err


@pytest.mark.parametrize("mapping, message", [
    ("tau: {topic: /ft/wrench, unit: mm}", "unit 'mm' is a length; input 'tau' needs a torque here"),
    ("tau: {topic: /ft/wrench, unit: [Nm, Nm]}", "input 'tau' is a torque: give 1 unit (a torque), not 2"),
    ("tau: {topic: /ft/wrench, unit: furlong}", "furlong"),
    ("tau: {topic: /ft/wrench, in: tool}", "unknown frame 'tool'"),
    ("tau: {topic: /ft/wrench, frame: tip}", "input 'tau' is a torque: recorded joints give a frame's pose"),
    ("tau: {unit: Nm}", "input 'tau''s recording needs `topic`"),
])
def test_a_bad_conversion_is_refused_at_its_line(tmp_path, capsys, mapping, message):
    write_bag(tmp_path / "lab")
    scene = _scene(tmp_path, f"recording:\n  bag: lab\n  inputs:\n    {mapping}\n")
    assert main(["simulate", str(PAPER_B), "--scene", str(scene)]) == 2
    err = capsys.readouterr().err
    assert message in err and "run.sim.yaml:" in err and "Traceback" not in err


def _documented_topics() -> dict[str, str]:
    """The MCAP topics docs/simulate.md lists, with their message types."""
    import re
    text = (TASKS_DIR.parent / "docs" / "simulate.md").read_text()
    table = text[text.index("| topic | message | what |"):].split("\n\n")[0]
    return {m.group(1): m.group(2) for m in re.finditer(r"^\| `(/[^`]+)` \| `([^`]+)`", table, re.M)}


@pytest.mark.parametrize("mode", ["closed", "open"])
def test_a_bag_drives_paper_b_and_the_mcap_it_writes_reads_back_with_every_documented_topic(tmp_path, mode):
    """The round trip of the issue: a bag written here (WrenchStamped at 1 kHz with 5 % jitter, JointState) drives
    paper B in both modes, the run is written as MCAP, and both `mcap` and `rosbags` read back every topic the docs
    list that paper B has (no phase, no haptic force), with the inputs equal to the bag's latest messages."""
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader
    joints, _ = _joints()
    stamps, torques = write_bag(tmp_path / "lab", joints=joints)
    body = ("recording:\n  bag: lab\n  inputs: {tau: /ft/wrench}\n" +
            ("  start: /joint_states\n" if mode == "closed" else "  mode: open\n  joints: /joint_states\n"))
    scene = _scene(tmp_path, body)
    out = tmp_path / "run.mcap"
    assert main(["simulate", str(PAPER_B), "--scene", str(scene), "--trace", str(out), "--quiet"]) == 0
    with out.open("rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    documented = _documented_topics()
    expected = {"/joint_states", "/tf", "/vfdsl/input/tau", "/vfdsl/status", "/vfdsl/violations",
                "/vfdsl/param/pivot", "/vfdsl/param/axis", "/vfdsl/fixtures"}
    for topic in expected:
        pattern = topic.replace("/tau", "/<input>").replace("/pivot", "/<param>").replace("/axis", "/<param>")
        assert topic in topics and documented[pattern].endswith(topics[topic].split("/")[-1]), topic
    assert any(t.startswith("/vfdsl/metric/") for t in topics)
    with AnyReader([out]) as reader:
        wrenches = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()
                    if c.topic == "/vfdsl/input/tau"]
    assert len(wrenches) == 80
    for k, w in enumerate(wrenches):
        latest = torques[np.searchsorted(stamps, k * 0.01 + 1e-12, side="right") - 1]
        assert np.array_equal([w.wrench.torque.x, w.wrench.torque.y, w.wrench.torque.z], latest)


def _pose(position, quaternion=(0.0, 0.0, 0.0, 1.0)):
    def build(T, header):
        x, y, z, w = quaternion
        return T["geometry_msgs/msg/PoseStamped"](header=header, pose=T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=position[0], y=position[1], z=position[2]),
            orientation=T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)))
    return build


@pytest.mark.parametrize("message, said", [
    (_pose([15.0, 0.0, 0.0]),
     "message 1 is refused by the task: input 'master' is a pose: its position is 15 m on axis x"),
    (_pose([0.0, 0.0, 0.0], (0.0, 0.0, 0.0, 0.0)), "message 1 has a zero orientation quaternion"),
])
def test_a_recorded_pose_the_task_refuses_is_refused_when_the_bag_is_read(tmp_path, capsys, message, said):
    """A master's pose recorded in millimetres as metres (15 m) or with an unset quaternion: refused naming the bag,
    the topic and the message (the first was refused mid-run without the bag, the second was a traceback)."""
    _write_topics(tmp_path / "lab", [("/master", "geometry_msgs/msg/PoseStamped", [_pose([0.0, 0.0, 0.0]), message],
                                      100)])
    scene = _scene(tmp_path, "recording:\n  bag: lab\n  inputs: {master: /master}\n")
    assert main(["simulate", str(TELEOP_LINE), "--scene", str(scene), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"bag lab, topic /master, {said}" in err and "run.sim.yaml:" in err and "Traceback" not in err, err
