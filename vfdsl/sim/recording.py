"""A lab's recording driving a simulation (a scene's ``recording:``): a ROS 2 bag (MCAP or sqlite3), an MCAP file or a
ROS 1 bag, read without ROS by ``rosbags``.

    recording:
      bag: runs/lab_session.mcap     # relative to the scene file: an .mcap or .db3 file, a rosbag2 folder, a ROS 1 .bag
      inputs:                        # task input: topic
        tau: /ft_sensor/wrench       # geometry_msgs/msg/WrenchStamped (a force takes its force, a torque its torque)
        master: {topic: /joint_states, frame: tip}   # a reference: the recorded joints -> task frame tip's pose
        f: {topic: /ft/wrench, unit: N, in: ft}      # conversions: the message's units, the frame it is expressed in
      start: /joint_states           # optional: the robot starts at the first sensor_msgs/msg/JointState, by joint name
      mode: closed                   # closed (default): the recorded inputs drive the simulated robot from the start;
      joints: /joint_states          # open: the recorded joints, and what the fixture would have commanded at each

Each mapped topic's messages are read once, when the scene is read, each stamped by its header (or, when the topic's
header stamps are all zero, by when it was recorded); time 0 is the earliest stamp of the mapped topics. At tick k (t =
k x the task's period) an input is the latest message stamped at or before t, as a controller reads the newest sample of
a sensor (a zero-order hold; before the first message, zero); after the last message it holds that one. The inputs are
in SI as ROS's messages are (N, N m, m/s, rad/s, m and a quaternion for a pose). A pose input mapped to a JointState
topic with ``frame:`` is a reference trajectory: at each message, the pose of that task frame at the recorded joints
(Pinocchio's forward kinematics of the task's robot), so that a recorded motion drives a ``teleop`` term (a new fixture
replayed on a motion recorded without it). Conversions, stated per input: ``unit:`` the units the message is in, one per
part (a force's, a wrench's force and torque, a twist's speed and angular speed, a pose's position), each checked
against its part's dimension; ``in:`` the task frame a force, torque, wrench or twist is expressed in (a sensor on the
tool), turned into the world at each tick by that frame's rotation at the tick's joints (the simulated robot's, or the
recorded ones in the open mode). In the open mode the robot is where the recorded joints say at each tick (the same
hold), the controller is stepped there with the recorded inputs, and its dq is recorded, not applied: what the fixture
would have commanded, and the rows it would have found violated.

Refused, each with the bag, the topic and the message's index: a topic the bag lacks (its topics listed) or that has
no message, a message type the input cannot take, stamps that go back in time or mix header stamps with zero ones, a
value that is NaN or inf (or a pose's zero quaternion) or that the input type's checks refuse (a pose 10 m away:
millimetres as metres), a vector input mapped without ``in:`` whose header names a frame other than the world's (a
sensor's own frame), a JointState naming a joint the robot lacks, missing one it has, naming one twice, with
another number of positions than names, or a position far outside its joint's limits (degrees recorded as radians).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from vfdsl import units as u
from vfdsl.errors import Span, VfError, suggest
from vfdsl.inputs import INPUT_TYPES
from vfdsl.runtime.values import admissible_joints

RECORDING_KEYS = ("bag", "mode", "inputs", "start", "joints")
MODES = ("closed", "open")
MESSAGE_TYPES = {"force": "geometry_msgs/msg/WrenchStamped", "torque": "geometry_msgs/msg/WrenchStamped",
                 "wrench": "geometry_msgs/msg/WrenchStamped", "twist": "geometry_msgs/msg/TwistStamped",
                 "pose": "geometry_msgs/msg/PoseStamped"}
"""The message an input of each type is read from (ROS 1 names are the same without ``msg/``)."""


@dataclass(frozen=True)
class RecordedInput:
    """One input's recorded values: the stamps (s, from the recording's time 0) and the values (rows, SI)."""

    input: str
    topic: str
    times: np.ndarray
    values: np.ndarray
    frame: str | None = None         # a reference: the pose of this task frame at the recorded joints
    expressed_in: str | None = None  # the task frame the vectors are in (turned into the world each tick)

    def at(self, t: float) -> np.ndarray:
        """The latest value stamped at or before t (zero before the first)."""
        k = int(np.searchsorted(self.times, t + 1e-12, side="right")) - 1
        return self.values[k] if k >= 0 else np.zeros(self.values.shape[1])

    def jitter(self) -> tuple[float, float, float]:
        """(median period, std of the periods, largest |period - median|) of the stamps, s."""
        steps = np.diff(self.times)
        if steps.size == 0:
            return 0.0, 0.0, 0.0
        median = float(np.median(steps))
        return median, float(np.std(steps)), float(np.max(np.abs(steps - median)))


@dataclass(frozen=True)
class Source:
    """Where one input is read from: its topic, the scene's place of the mapping, a reference's task frame, the
    task frame its vectors are expressed in, and the factor to SI of each part."""

    topic: str
    span: Span
    frame: str | None = None
    expressed_in: str | None = None
    factors: tuple[float, ...] = ()
    in_stated: bool = False          # the mapping says `in:` (world included): the messages' frame_id is not read


@dataclass(frozen=True)
class Recording:
    bag: str
    inputs: tuple[RecordedInput, ...]
    start: np.ndarray | None = None
    where: Span | None = None
    summary: dict = field(default_factory=dict)
    mode: str = "closed"
    joints: RecordedInput | None = None      # the open mode's recorded joints (the robot's joint order)


def read_recording(reader, node: yaml.Node) -> Recording:
    """The scene's ``recording:`` (``reader``: the scene reader), its bag read now."""
    fields = reader.mapping(node, RECORDING_KEYS, "the recording")
    if "bag" not in fields:
        raise VfError("the recording needs 'bag'", reader.pos(node), hint="recording: {bag: run.mcap, inputs: {...}}",
                      code="E602")
    bag = Path(reader.text(fields["bag"][1], "bag"))
    if not bag.is_absolute():
        bag = Path(reader.file).resolve().parent / bag
    if not bag.exists():
        raise VfError(f"no bag at {bag}", reader.pos(fields["bag"][1]), code="E602")
    mapping = {}
    if "inputs" in fields:
        inputs_node = fields["inputs"][1]
        if not isinstance(inputs_node, yaml.MappingNode):
            raise VfError("the recording's inputs map task inputs to topics, like tau: /ft_sensor/wrench",
                          reader.pos(inputs_node), code="E602")
        names = [i.name for i in reader.task.inputs]
        for key, (key_node, value) in reader.fields(inputs_node).items():
            if key not in names:
                raise VfError(f"the recording maps '{key}', which task '{reader.task.name}' does not declare",
                              reader.pos(key_node), hint=suggest(key, names, "inputs"), code="E602")
            kind = reader.task.input(key).type
            if kind not in MESSAGE_TYPES:
                raise VfError(f"input '{key}' is a {kind}: no recorded message type maps to it",
                              reader.pos(key_node), hint="map force, torque, wrench, twist or pose inputs",
                              code="E602")
            mapping[key] = _input_source(reader, key, kind, value)
    start = (reader.text(fields["start"][1], "a topic"), reader.pos(fields["start"][1])) if "start" in fields else None
    mode = reader.text(fields["mode"][1], "mode") if "mode" in fields else "closed"
    if mode not in MODES:
        raise VfError(f"unknown recording mode '{mode}'", reader.pos(fields["mode"][1]),
                      hint="closed: the recorded inputs drive the simulated robot; open: the recorded joints, and what "
                           "the fixture would have commanded there", code="E602")
    joints = (reader.text(fields["joints"][1], "a topic"), reader.pos(fields["joints"][1])) if "joints" in fields \
        else None
    if mode == "open" and start is not None:
        raise VfError("the open mode starts where the recorded joints do: drop `start`", reader.pos(fields["start"][0]),
                      code="E602")
    if (mode == "open") != (joints is not None):
        raise VfError("the open mode replays recorded joints: give `joints: TOPIC` (a JointState topic)" if joints is None
                      else "recorded joints are replayed in the open mode only: add `mode: open`",
                      reader.pos(node), code="E602")
    if not mapping and start is None and joints is None:
        raise VfError("the recording maps no input and no start", reader.pos(node), code="E602")
    return load(bag, reader.task, mapping, start or joints, reader.pos(node), mode, joints)


def _input_source(reader, key: str, kind: str, node: yaml.Node) -> Source:
    """One input's mapping: ``TOPIC``, or ``{topic: TOPIC, unit: ..., in: FRAME}`` with conversions, or
    ``{topic: TOPIC, frame: FRAME}`` for a pose input read from recorded joints."""
    if not isinstance(node, yaml.MappingNode):
        return Source(reader.text(node, "a topic"), reader.pos(node))
    fields = reader.mapping(node, ("topic", "frame", "unit", "in"), f"input '{key}''s recording")
    if "topic" not in fields:
        raise VfError(f"input '{key}''s recording needs `topic`", reader.pos(node), code="E602")
    topic, span = reader.text(fields["topic"][1], "a topic"), reader.pos(fields["topic"][1])
    if "frame" in fields:
        if kind != "pose":
            raise VfError(f"input '{key}' is a {kind}: recorded joints give a frame's pose, so only a pose input reads "
                          "them (`frame:`)", reader.pos(fields["frame"][0]), code="E602")
        extra = [k for k in ("unit", "in") if k in fields]
        if extra:
            raise VfError(f"a reference from recorded joints is the frame's pose in the world, in SI: drop `{extra[0]}`",
                          reader.pos(fields[extra[0]][0]), code="E602")
        return Source(topic, span, frame=reader.frame(fields["frame"][1]))
    expressed_in = None
    if "in" in fields:
        if kind not in ("force", "torque", "wrench", "twist"):
            raise VfError(f"input '{key}' is a {kind}: `in:` turns a force, torque, wrench or twist into the world",
                          reader.pos(fields["in"][0]), code="E602")
        name = reader.text(fields["in"][1], "a frame")
        expressed_in = None if name == "world" else reader.frame(fields["in"][1])
    parts = INPUT_TYPES[kind].parts[:1] if kind == "pose" else INPUT_TYPES[kind].parts
    factors = tuple(1.0 for _ in parts)
    if "unit" in fields:
        unit_node = fields["unit"][1]
        names = ([reader.text(x, "a unit") for x in unit_node.value] if isinstance(unit_node, yaml.SequenceNode)
                 else [reader.text(unit_node, "a unit")])
        if len(names) != len(parts):
            raise VfError(f"input '{key}' is a {kind}: give {len(parts)} unit{'s' * (len(parts) > 1)} ("
                          + ", ".join(u.describe(p.dimension) for p in parts) + f"), not {len(names)}",
                          reader.pos(unit_node), code="E602")
        converted = []
        for name, part in zip(names, parts):
            dim, factor = u.parse_unit(name, reader.pos(unit_node))
            if dim != part.dimension:
                raise VfError(f"unit '{name}' is {u.describe(dim)}; input '{key}' needs {u.describe(part.dimension)} "
                              f"here", reader.pos(unit_node), hint=f"write {u.example(part.dimension)}", code="E602")
            converted.append(factor)
        factors = tuple(converted)
    return Source(topic, span, expressed_in=expressed_in, factors=factors, in_stated="in" in fields)


def load(bag: Path, task, mapping: dict[str, Source], start: tuple[str, Span] | None,
         where: Span | None, mode: str = "closed", joints: tuple[str, Span] | None = None) -> Recording:
    """Read every mapped topic of ``bag`` (module docstring); VfError at the scene's line of the mapping."""
    from rosbags.highlevel import AnyReader
    from vfdsl.kinematics.robot import Robot
    robot = Robot.load(task.robots[0].urdf)
    try:
        reader = AnyReader([bag])
        reader.open()
    except Exception as exc:          # rosbags' own errors: not a bag, an unknown storage, a damaged file
        raise VfError(f"cannot read the bag {bag}: {exc}", where, code="E602") from None
    try:
        topics = {c.topic: c for c in reader.connections}
        read = {}
        wanted = {name: source.topic for name, source in mapping.items()}
        if start is not None:
            wanted["(start)"] = start[0]
        for name, topic in wanted.items():
            span = mapping[name].span if name in mapping else start[1]
            if topic not in topics:
                raise VfError(f"bag {bag.name} has no topic {topic}", span,
                              hint=suggest(topic, topics, "topics"), code="E602")
            joints_read = name == "(start)" or mapping[name].frame is not None
            expected = "sensor_msgs/msg/JointState" if joints_read else MESSAGE_TYPES[task.input(name).type]
            got = topics[topic].msgtype
            if got.replace("/msg/", "/") != expected.replace("/msg/", "/"):
                raise VfError(f"bag {bag.name}, topic {topic}: {got} messages, but "
                              f"{'the start' if name == '(start)' else f'input {name!r}'} reads {expected}", span,
                              code="E602")
            try:
                read[name] = (span, [(stamp, reader.deserialize(raw, connection.msgtype)) for connection, stamp, raw
                                     in reader.messages(connections=[topics[topic]])])
            except Exception as exc:  # a damaged chunk or message past the summary rosbags opened
                raise VfError(f"cannot read bag {bag.name}, topic {topic}: {exc}", span, code="E602") from None
            if not read[name][1]:
                raise VfError(f"bag {bag.name}, topic {topic}: no message", span, code="E602")
    finally:
        reader.close()
    stamped = {name: (span, _stamps(bag.name, wanted[name], span, messages), messages)
               for name, (span, messages) in read.items()}
    origin = min(float(times[0]) for _, times, _ in stamped.values() if len(times))
    inputs = []
    for name, (span, times, messages) in stamped.items():
        if name == "(start)":
            continue
        source = mapping[name]
        if source.frame is None:
            if not source.in_stated:
                _in_the_world(name, robot, (bag.name, wanted[name], span), messages)
            values = np.array([_value(task.input(name).type, m, (bag.name, wanted[name], span, k))
                               for k, (_, m) in enumerate(messages)]).reshape(len(messages), -1)
            for k, factor in enumerate(source.factors):           # each part's units to SI
                values[:, 3 * k:3 * k + 3] *= factor
        else:
            values = _frame_poses(robot, task.frame(source.frame), [
                _joints(bag.name, wanted[name], span, m, robot, k) for k, (_, m) in enumerate(messages)])
        for k, value in enumerate(values):                      # the input type's checks, as Controller.step's
            failed = INPUT_TYPES[task.input(name).type].first_failure(value)
            if failed:
                raise _message_error((bag.name, wanted[name], span, k),
                                     f"is refused by the task: {failed[0].message(name, failed[1], value)}")
        inputs.append(RecordedInput(name, wanted[name], times - origin, values, source.frame, source.expressed_in))
    q0, replayed = None, None
    if start is not None:
        span, times, messages = stamped["(start)"]
        q0 = _joints(bag.name, start[0], span, messages[0][1], robot)
        if joints is not None:
            q = np.array([_joints(bag.name, start[0], span, m, robot, k) for k, (_, m) in
                          enumerate(messages)])
            replayed = RecordedInput("(joints)", joints[0], times - origin, q)
    summary = {"bag": str(bag), "mode": mode, "inputs": {r.input: r.topic for r in inputs},
               "start": None if start is None else start[0]}
    return Recording(str(bag), tuple(inputs), q0, where, summary, mode, replayed)


def _frame_poses(robot, frame, joints: list[np.ndarray]) -> np.ndarray:
    """The pose (x, y, z, roll, pitch, yaw) of task frame ``frame`` at each recorded joint vector."""
    from scipy.spatial.transform import Rotation
    from vfdsl.compiler.geometry import homogeneous
    offset = homogeneous(frame.offset, frame.rpy)
    poses = [robot.frame_pose(q, frame.link, offset) for q in joints]
    return np.array([np.r_[p, Rotation.from_matrix(R).as_euler("xyz")] for p, R in poses]).reshape(len(joints), 6)


def _stamps(bag: str, topic: str, span: Span, messages: list) -> np.ndarray:
    """Each message's stamp (s): its header's, or, when every header stamp of the topic is zero, when it was recorded
    (one clock per topic: a zero among header stamps is refused); increasing."""
    headers = []
    for recorded, message in messages:
        stamp = getattr(getattr(message, "header", None), "stamp", None)
        headers.append(0.0 if stamp is None else stamp.sec + 1e-9 * stamp.nanosec)
    zero, stamped = [k for k, h in enumerate(headers) if not h > 0], [k for k, h in enumerate(headers) if h > 0]
    if zero and stamped:
        raise VfError(f"bag {bag}, topic {topic}: message {zero[0]} has a zero header stamp and message {stamped[0]} "
                      "has one: its times would mix the sensor's clock with the recorder's", span,
                      hint="stamp every message of the topic (or none: then each is timed by when it was recorded)",
                      code="E602")
    times = headers if stamped else [recorded * 1e-9 for recorded, _ in messages]
    times = np.array(times, dtype=float)
    back = np.flatnonzero(np.diff(times) < 0)
    if back.size:
        k = int(back[0]) + 1
        raise VfError(f"bag {bag}, topic {topic}: message {k} is stamped {times[k]:.6f} s, before message {k - 1} "
                      f"({times[k - 1]:.6f} s): the stamps go back in time", span,
                      hint="record with the sensor's own stamps, or fix the driver's clock", code="E602")
    return times


def _message_error(where: tuple, text: str, hint: str | None = None) -> VfError:
    """A refusal of message ``index`` of a topic: ``where`` is (bag, topic, span, index)."""
    bag, topic, span, index = where
    return VfError(f"bag {bag}, topic {topic}, message {index} {text}", span, hint=hint, code="E602")


def _finite(where: tuple, what: str, values) -> np.ndarray:
    """``values`` as floats, refused (naming the message) when one is NaN or inf."""
    values = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(values)):
        raise _message_error(where, f"holds NaN or inf in its {what}: {values.tolist()}",
                             hint="a sensor's dropout recorded as NaN: cut it from the bag, or fill it")
    return values


def _value(type_name: str, message, where: tuple) -> np.ndarray:
    """An input's value from its message (SI); ``where`` (bag, topic, span, index) names it when refused."""
    if type_name == "pose":
        from scipy.spatial.transform import Rotation
        p, o = message.pose.position, message.pose.orientation
        position = _finite(where, "position", [p.x, p.y, p.z])
        quaternion = _finite(where, "orientation", [o.x, o.y, o.z, o.w])
        if not np.linalg.norm(quaternion) > 1e-6:
            raise _message_error(where, f"has a zero orientation quaternion {quaternion.tolist()}: no rotation",
                                 hint="an unset orientation is (x, y, z, w) = (0, 0, 0, 1)")
        return np.r_[position, Rotation.from_quat(quaternion).as_euler("xyz")]
    if type_name == "twist":
        v, w = message.twist.linear, message.twist.angular
        return _finite(where, "twist", [v.x, v.y, v.z, w.x, w.y, w.z])
    f, t = message.wrench.force, message.wrench.torque
    parts = {"force": [f.x, f.y, f.z], "torque": [t.x, t.y, t.z], "wrench": [f.x, f.y, f.z, t.x, t.y, t.z]}
    return _finite(where, type_name, parts[type_name])


def _in_the_world(name: str, robot, where: tuple, messages: list) -> None:
    """An input mapped without `in:` is read in the world: refused when a message's header names another frame
    (frame_id neither empty, 'world' nor the robot's base link), a sensor's own frame, which would be taken as the
    world's axes."""
    base = robot.link_names()[0]
    for k, (_, message) in enumerate(messages):
        frame_id = str(getattr(getattr(message, "header", None), "frame_id", "") or "")
        if frame_id not in ("", "world", base):
            raise _message_error((*where, k), f"is expressed in frame '{frame_id}' (its header's frame_id), but input "
                                 f"'{name}' is read in the world ('{base}', the robot's base)",
                                 hint=f"say which task frame '{frame_id}' is: `{{topic: ..., in: FRAME}}` (its vectors "
                                      "are then turned into the world each tick), or `in: world` if its axes are the "
                                      "world's")


def _joints(bag: str, topic: str, span: Span, message, robot, index: int = 0) -> np.ndarray:
    """The robot's joints from a JointState (message ``index`` of its topic), by name: each joint of the robot
    named once, no other, one position per name, every position finite and admissible (as Controller.step's q)."""
    where, joints = (bag, topic, span, index), robot.joint_names
    names = list(message.name)
    unknown = [n for n in names if n not in joints]
    if unknown:
        raise _message_error(where, f"names joint '{unknown[0]}', which the robot lacks",
                             hint=suggest(unknown[0], joints, "joints"))
    twice = [n for k, n in enumerate(names) if n in names[:k]]
    if twice:
        raise _message_error(where, f"names joint '{twice[0]}' twice")
    missing = [j for j in joints if j not in names]
    if missing:
        raise _message_error(where, f"has no position of joint '{missing[0]}'")
    if len(message.position) != len(names):
        raise _message_error(where, f"names {len(names)} joints but has {len(message.position)} positions")
    q = _finite(where, "positions", message.position)[[names.index(j) for j in joints]]
    low, high = admissible_joints(robot.lower, robot.upper)
    outside = np.flatnonzero((q < low) | (q > high))
    if outside.size:
        i = int(outside[0])
        raise _message_error(where, f"puts joint '{joints[i]}' at {q[i]:.6g}, far outside its limits "
                             f"[{robot.lower[i]:.6g}, {robot.upper[i]:.6g}] (SI: m or rad)",
                             hint="a JointState is in radians and metres: degrees or millimetres recorded?")
    return q


def late_inputs(recording: Recording, end: float) -> list[tuple[float, str, Span | None]]:
    """Recorded inputs whose first message is stamped at or after ``end`` (s from the recording's time 0): they read
    zero the whole run. (start, what, where) of each, as :func:`vfdsl.sim.scripted.late_events`."""
    return [(float(r.times[0]), (f"input '{r.input}''s recording ({r.topic}, its first message stamped "
                                 f"{r.times[0]:.6g} s after the recording's time 0, the earliest stamp of its mapped "
                                 "topics: stamped by another clock?)"), recording.where)
            for r in recording.inputs if r.times[0] >= end - 1e-12]


def recording_text(recording: Recording, period: float) -> str:
    """What the heading of a run says of its recording: each input's topic, messages, rate and jitter."""
    parts = []
    for r in recording.inputs:
        median, std, worst = r.jitter()
        rate = f"{1 / median:.4g} Hz" if median > 0 else "one message"
        source = r.topic if r.frame is None else f"{r.topic} ({r.frame}'s pose at the recorded joints)"
        source += "" if r.expressed_in is None else f" (in {r.expressed_in}, turned into the world each tick)"
        parts.append(f"'{r.input}' <- {source} ({len(r.times)} messages over {r.times[-1] - r.times[0]:.3g} s, "
                     f"{rate}, period jitter {std * 1e3:.3g} ms RMS, {worst * 1e3:.3g} ms at most)")
    text = "; ".join(parts) + f"; each tick ({period * 1e3:g} ms) reads the latest message"
    if recording.joints is not None:
        text += (f"; open loop: the joints from {recording.joints.topic} ({len(recording.joints.times)} messages), the "
                 "controller's dq recorded, not applied")
    elif recording.start is not None:
        text += f"; the start from {recording.summary['start']}"
    return f"{Path(recording.bag).name}: {text}"
