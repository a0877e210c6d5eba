"""The per-tick trace as an MCAP file of standard ROS 2 messages (``vfdsl simulate --trace run.mcap``), for Foxglove,
PlotJuggler or RViz beside the rest of a lab's data. No ROS installation: the messages are built and serialized
(CDR) by ``rosbags``' type store (ROS 2 Humble's standard messages), the file written by ``mcap`` with each
message definition as its schema (encoding ``ros2msg``), so that ``mcap`` and ``rosbags`` read it back.

Topics (one message per tick on each but the markers, stamped with the tick's time t = k * period from 0, in ns):

    /joint_states                  sensor_msgs/msg/JointState: q (position) and dq / period (velocity), by joint name
    /tf                            tf2_msgs/msg/TFMessage: every task frame's pose, world -> <frame> (Pinocchio); none
                                   at a tick whose joints are not finite (a refused tick of an exported replay)
    /vfdsl/input/<input>           a force, torque or wrench: geometry_msgs/msg/WrenchStamped; a twist:
                                   geometry_msgs/msg/TwistStamped; a pose: geometry_msgs/msg/PoseStamped; a button:
                                   std_msgs/msg/Bool
    /vfdsl/status                  std_msgs/msg/Int32: the step's status flags (0 optimal, +1 least violation, ...)
    /vfdsl/violations              std_msgs/msg/String: what the step left violated (empty when nothing)
    /vfdsl/metric/<name>           std_msgs/msg/Float64: each metric in SI (the trace's metric.<name> columns),
                                   skipped at ticks where it has no value
    /vfdsl/param/<param>           std_msgs/msg/Float64MultiArray: each run-time param as the controller had it, its
                                   flat value in SI (the trace's param.<param>. columns, in their order)
    /vfdsl/phase                   std_msgs/msg/String: a procedure's phase
    /vfdsl/haptic                  geometry_msgs/msg/WrenchStamped: a teleoperated run's haptic force (master base)
    /vfdsl/fixtures                visualization_msgs/msg/MarkerArray: the fixtures' geometry, as ``vfdsl view`` draws
                                   it (:mod:`vfdsl.sim.markers`), at up to 10 Hz and only the markers that changed

Frames: ``world`` for the inputs, the TF parent and the haptic force. A run of several trials (or a grid) puts each
trial's topics under ``/trial_<k>`` (k its index among the traced trials, in the trace's order).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vfdsl.compiler.context import unflatten
from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.sim import trace as tr
from vfdsl.sim.geometry import Scene
from vfdsl.sim.markers import MARKER_RATE, FixtureMarkers, shape_frames
from vfdsl.sim.metrics import frame_poses

WORLD = "world"


class _Channels:
    """The writer's schemas and channels, registered as topics first appear, and the messages' constructors."""

    def __init__(self, writer):
        from rosbags.typesys import Stores, get_typestore
        self.store = get_typestore(Stores.ROS2_HUMBLE)
        self.types = self.store.types
        self.writer = writer
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}

    def write(self, topic: str, typename: str, message, ns: int) -> None:
        if topic not in self._channels:
            if typename not in self._schemas:
                text = self.store.generate_msgdef(typename)[0]
                self._schemas[typename] = self.writer.register_schema(name=typename, encoding="ros2msg",
                                                                      data=text.encode())
            self._channels[topic] = (self.writer.register_channel(topic=topic, message_encoding="cdr",
                                                                  schema_id=self._schemas[typename]), typename)
        channel, _ = self._channels[topic]
        self.writer.add_message(channel, log_time=ns, publish_time=ns,
                                data=bytes(self.store.serialize_cdr(message, typename)))

    def header(self, ns: int, frame: str = WORLD):
        T = self.types
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000,
                                                                              nanosec=ns % 1_000_000_000),
                                        frame_id=frame)

    def vector(self, xyz):
        return self.types["geometry_msgs/msg/Vector3"](x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))

    def quaternion(self, R):
        from scipy.spatial.transform import Rotation
        x, y, z, w = Rotation.from_matrix(R).as_quat()
        return self.types["geometry_msgs/msg/Quaternion"](x=float(x), y=float(y), z=float(z), w=float(w))

    def wrench(self, ns: int, force, torque):
        T = self.types
        return T["geometry_msgs/msg/WrenchStamped"](header=self.header(ns), wrench=T["geometry_msgs/msg/Wrench"](
            force=self.vector(force), torque=self.vector(torque)))


def write_mcap(path: Path, results, task: ir.Task) -> None:
    """Every traced trial of ``results`` into the MCAP file ``path`` (module docstring)."""
    from mcap.writer import Writer

    traced = [r for r in results if r.trace is not None]
    robot = Robot.load(task.robots[0].urdf)
    with Path(path).open("wb") as out:
        writer = Writer(out)
        writer.start(profile="ros2", library="vfdsl")
        channels = _Channels(writer)
        for k, result in enumerate(traced):
            _trial(channels, result.trace, task, robot, f"/trial_{k}" if len(traced) > 1 else "")
        writer.finish()


def _trial(ch: _Channels, trace: dict, task: ir.Task, robot: Robot, prefix: str) -> None:
    T = ch.types
    times = np.asarray(trace["t_s"], dtype=float)
    period = float(times[1] - times[0]) if len(times) > 1 else 1.0
    q = np.column_stack([trace[c] for c in tr.joint_columns("q", robot.joint_names, robot.joint_types)])
    dq = np.column_stack([trace[c] for c in tr.joint_columns("dq", robot.joint_names, robot.joint_types)])
    inputs = {i.name: np.column_stack([trace[f"input.{i.name}.{part}"] for part in INPUT_TYPES[i.type].columns])
              for i in task.inputs if f"input.{i.name}.{INPUT_TYPES[i.type].columns[0]}" in trace}
    metrics = {c[len("metric."):]: np.asarray(trace[c], dtype=float) for c in trace if c.startswith("metric.")}
    params = {d.name: np.column_stack([trace[c] for c in tr.param_columns(d)]) for d in tr.runtime_params(task)
              if tr.param_columns(d)[0] in trace}
    layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    haptic = (np.column_stack([trace[f"haptic_{a}_N"] for a in "xyz"]) if "haptic_x_N" in trace else None)
    placed = np.all(np.isfinite(q), axis=1)          # a refused tick's NaN joints: no TF and no markers there
    poses = frame_poses(robot, task, np.where(placed[:, None], q, 0.0))
    markers, scene = FixtureMarkers(task, T), Scene(task)
    every, drawn = max(1, int(round(1.0 / (MARKER_RATE * period)))), 0
    for k, t in enumerate(times):
        ns = int(round(t * 1e9))
        ch.write(f"{prefix}/joint_states", "sensor_msgs/msg/JointState", T["sensor_msgs/msg/JointState"](
            header=ch.header(ns, ""), name=list(robot.joint_names), position=q[k].astype(float),
            velocity=(dq[k] / period).astype(float), effort=np.zeros(0)), ns)
        at = {f.name: (poses.p[f.name][k], poses.R[f.name][k]) for f in task.frames} if placed[k] else {}
        if placed[k]:
            ch.write(f"{prefix}/tf", "tf2_msgs/msg/TFMessage", T["tf2_msgs/msg/TFMessage"](transforms=[
                T["geometry_msgs/msg/TransformStamped"](
                    header=ch.header(ns), child_frame_id=name,
                    transform=T["geometry_msgs/msg/Transform"](translation=ch.vector(p), rotation=ch.quaternion(R)))
                for name, (p, R) in at.items()]), ns)
        for decl in task.inputs:
            if decl.name in inputs:
                _input(ch, f"{prefix}/vfdsl/input/{decl.name}", INPUT_TYPES[decl.type], inputs[decl.name][k], ns)
        ch.write(f"{prefix}/vfdsl/status", "std_msgs/msg/Int32", T["std_msgs/msg/Int32"](data=int(trace["status"][k])),
                 ns)
        ch.write(f"{prefix}/vfdsl/violations", "std_msgs/msg/String",
                 T["std_msgs/msg/String"](data=str(trace["violations"][k])), ns)
        for name, values in metrics.items():
            if np.isfinite(values[k]):
                ch.write(f"{prefix}/vfdsl/metric/{name}", "std_msgs/msg/Float64",
                         T["std_msgs/msg/Float64"](data=float(values[k])), ns)
        for name, values in params.items():
            ch.write(f"{prefix}/vfdsl/param/{name}", "std_msgs/msg/Float64MultiArray",
                     T["std_msgs/msg/Float64MultiArray"](layout=layout, data=values[k].astype(float)), ns)
        if "phase" in trace:
            ch.write(f"{prefix}/vfdsl/phase", "std_msgs/msg/String", T["std_msgs/msg/String"](data=str(trace["phase"][k])),
                     ns)
        if haptic is not None:
            ch.write(f"{prefix}/vfdsl/haptic", "geometry_msgs/msg/WrenchStamped", ch.wrench(ns, haptic[k], np.zeros(3)),
                     ns)
        if placed[k] and (k % every == 0 or k == len(times) - 1):
            moved = [name for name, values in params.items() if k == 0 or not np.array_equal(values[k], values[drawn])]
            for name in moved:
                scene.set_value(name, unflatten(scene.values[name], params[name][k]))
            changed, drawn = markers.update(ch.header(ns), scene, shape_frames(task, at), bool(moved)), k
            if changed:
                ch.write(f"{prefix}/vfdsl/fixtures", "visualization_msgs/msg/MarkerArray",
                         T["visualization_msgs/msg/MarkerArray"](markers=changed), ns)


def _input(ch: _Channels, topic: str, kind, value: np.ndarray, ns: int) -> None:
    """One input's message, by its type (module docstring)."""
    T = ch.types
    if kind.switch:
        ch.write(topic, "std_msgs/msg/Bool", T["std_msgs/msg/Bool"](data=bool(value[0] > 0.5)), ns)
    elif kind.name == "pose":
        from vfdsl.compiler.geometry import rotation
        pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](
            x=float(value[0]), y=float(value[1]), z=float(value[2])), orientation=ch.quaternion(rotation(value[3:6])))
        ch.write(topic, "geometry_msgs/msg/PoseStamped", T["geometry_msgs/msg/PoseStamped"](header=ch.header(ns),
                                                                                          pose=pose), ns)
    elif kind.name == "twist":
        twist = T["geometry_msgs/msg/Twist"](linear=ch.vector(value[0:3]), angular=ch.vector(value[3:6]))
        ch.write(topic, "geometry_msgs/msg/TwistStamped", T["geometry_msgs/msg/TwistStamped"](header=ch.header(ns),
                                                                                            twist=twist), ns)
    else:
        force = value[kind.linear_range] if kind.linear is not None else np.zeros(3)
        torque = value[kind.angular_range] if kind.angular is not None else np.zeros(3)
        ch.write(topic, "geometry_msgs/msg/WrenchStamped", ch.wrench(ns, force, torque), ns)
