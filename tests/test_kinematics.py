"""Symbolic kinematics (CasADi) against Pinocchio, against finite differences, and the Robot API's errors."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from vfdsl.errors import VfError
from vfdsl.kinematics import Robot, SymbolicKinematics

N_RANDOM = 1000
TOL = 1e-10


def _transform(rpy, xyz) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
    T[:3, 3] = xyz
    return T


OFFSET = _transform([0.3, -0.7, 1.1], [0.02, -0.05, 0.1])


def random_q(robot: Robot, n: int, seed: int) -> np.ndarray:
    """n x nq configurations, uniform within limits (continuous joints: within +-2 pi)."""
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -2 * np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, 2 * np.pi)
    return rng.uniform(lo, hi, size=(n, robot.nq))


def symbolic_batch(robot: Robot, link: str, offset, qs: np.ndarray):
    """Symbolic p (n x 3), R (n x 3 x 3), J (n x 6 x nq) at every row of qs, in one mapped call."""
    kin = SymbolicKinematics(robot)
    f = kin.frame(link, offset)
    fun = ca.Function("fk", [kin.q], [f.p, ca.vec(f.R), ca.vec(f.J)]).map(len(qs))
    p, R, J = (np.asarray(out) for out in fun(qs.T))
    n = len(qs)
    return p.T, R.T.reshape(n, 3, 3).transpose(0, 2, 1), J.T.reshape(n, robot.nq, 6).transpose(0, 2, 1)


def pinocchio_batch(robot: Robot, link: str, offset, qs: np.ndarray):
    """Pinocchio's frame pose and LOCAL_WORLD_ALIGNED Jacobian; the offset becomes an extra OP_FRAME."""
    model = robot.model.copy()
    fid = robot.frame_id(link)
    if offset is not None:
        parent = model.frames[fid]
        fid = model.addFrame(pin.Frame("task", parent.parentJoint, fid,
                                       parent.placement * pin.SE3(offset), pin.FrameType.OP_FRAME))
    data = model.createData()
    p, R, J = [], [], []
    for q in qs:
        qp = robot.to_pinocchio(q)
        pin.computeJointJacobians(model, data, qp)
        pin.updateFramePlacements(model, data)
        p.append(data.oMf[fid].translation.copy())
        R.append(data.oMf[fid].rotation.copy())
        J.append(pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
    return np.array(p), np.array(R), np.array(J)


@pytest.fixture(scope="module", params=["shr7", "panda7", "psm6"])
def robot(request) -> Robot:
    return Robot.load(request.param)


@pytest.mark.parametrize("offset", [None, OFFSET], ids=["link", "offset"])
def test_symbolic_matches_pinocchio(robot, offset):
    qs = random_q(robot, N_RANDOM, seed=1)
    for got, want in zip(symbolic_batch(robot, "tool_tip", offset, qs),
                         pinocchio_batch(robot, "tool_tip", offset, qs)):
        np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


@pytest.mark.parametrize("offset", [None, OFFSET], ids=["link", "offset"])
def test_robot_numeric_api_matches_pinocchio(robot, offset):
    qs = random_q(robot, 50, seed=2)
    p, R, J = pinocchio_batch(robot, "tool_tip", offset, qs)
    for k, q in enumerate(qs):
        pk, Rk = robot.frame_pose(q, "tool_tip", offset)
        np.testing.assert_allclose(pk, p[k], rtol=0, atol=TOL)
        np.testing.assert_allclose(Rk, R[k], rtol=0, atol=TOL)
        np.testing.assert_allclose(robot.frame_jacobian(q, "tool_tip", offset), J[k], rtol=0, atol=TOL)


def test_jacobian_matches_finite_differences(robot):
    """Column i of J is d/dq_i of [p; log(R(q + h e_i) R(q - h e_i)^T) / 2]."""
    kin = SymbolicKinematics(robot)
    f = kin.frame("tool_tip", OFFSET)
    fk = ca.Function("fk", [kin.q], [f.p, f.R, f.J])
    h = 1e-6
    for q in random_q(robot, 5, seed=3):
        J = np.asarray(fk(q)[2])
        for i in range(robot.nq):
            dq = np.zeros(robot.nq)
            dq[i] = h
            p1, R1, _ = (np.asarray(x) for x in fk(q + dq))
            p0, R0, _ = (np.asarray(x) for x in fk(q - dq))
            np.testing.assert_allclose((p1 - p0).ravel() / (2 * h), J[:3, i], rtol=0, atol=1e-7)
            np.testing.assert_allclose(pin.log3(R1 @ R0.T) / (2 * h), J[3:, i], rtol=0, atol=1e-7)


TREE_URDF = """<?xml version="1.0"?>
<robot name="tree">
  <link name="base"/>
  <link name="a"/><link name="b"/><link name="c"/><link name="d"/><link name="e"/>
  <link name="f"/><link name="g"/><link name="h"/><link name="tip"/>
  <joint name="spin" type="continuous">
    <parent link="base"/><child link="a"/><origin xyz="0.1 0 0.2" rpy="0 0 0.4"/><axis xyz="0 0 1"/>
  </joint>
  <joint name="tilt" type="revolute">
    <parent link="a"/><child link="b"/><origin xyz="0 0.05 0.3" rpy="0.2 -0.1 0"/>
    <axis xyz="2.4 3 3.2"/><limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="mount" type="fixed">
    <parent link="b"/><child link="c"/><origin xyz="0.02 -0.03 0.15" rpy="1.0 0.5 -0.7"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="c"/><child link="d"/><origin xyz="0 0 0.1" rpy="0 0.3 0"/>
    <axis xyz="0.6 0 -0.8"/><limit lower="-0.2" upper="0.2" effort="1" velocity="1"/>
  </joint>
  <joint name="wrist" type="continuous">
    <parent link="d"/><child link="e"/><origin xyz="0.05 0 0" rpy="0 0 0"/><axis xyz="0 -0.6 0.8"/>
  </joint>
  <joint name="flip" type="revolute">
    <parent link="e"/><child link="f"/><origin xyz="0 0 0.07" rpy="0 0 0"/>
    <axis xyz="0 -1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="tool" type="fixed">
    <parent link="f"/><child link="tip"/><origin xyz="0 0.01 0.12" rpy="-0.4 0.2 0.9"/>
  </joint>
  <joint name="side" type="prismatic">
    <parent link="a"/><child link="g"/><origin xyz="0.2 0 0" rpy="0 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-0.1" upper="0.1" effort="1" velocity="1"/>
  </joint>
  <joint name="side_tool" type="fixed">
    <parent link="g"/><child link="h"/><origin xyz="0 0 0.05" rpy="0.3 0 0"/>
  </joint>
</robot>
"""


def test_symbolic_matches_pinocchio_on_a_tree_with_every_joint_kind(tmp_path):
    path = tmp_path / "tree.urdf"
    path.write_text(TREE_URDF)
    robot = Robot.load(str(path))
    kinds = {j.shortname() for j in robot.model.joints[1:]}
    assert {"JointModelRUBZ", "JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned",
            "JointModelRevoluteUnboundedUnaligned", "JointModelPY"} <= kinds
    assert robot.joint_types.count("continuous") == 2
    cont = [i for i, t in enumerate(robot.joint_types) if t == "continuous"]
    assert np.all(np.isinf(robot.lower[cont])) and np.all(np.isinf(robot.upper[cont]))
    qs = random_q(robot, 200, seed=4)
    for link in ("tip", "h", "c", "base"):
        for got, want in zip(symbolic_batch(robot, link, OFFSET, qs), pinocchio_batch(robot, link, OFFSET, qs)):
            np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


def test_frames_share_one_coordinate_vector():
    robot = Robot.load("shr7")
    q = ca.SX.sym("theta", robot.nq)
    kin = SymbolicKinematics(robot, q)
    assert kin.q is q
    tip, holder = kin.frame("tool_tip"), kin.frame("tool_holder")
    fun = ca.Function("two", [q], [tip.p, holder.p])
    p_tip, p_holder = fun(np.zeros(robot.nq))
    np.testing.assert_allclose(np.asarray(p_holder) - np.asarray(p_tip), [[0], [0], [0.1]], atol=1e-14)


# --- errors: always VfError, never a raw pinocchio/boost exception -----------------------------------------

def test_unknown_shipped_robot():
    with pytest.raises(VfError, match="shr8") as err:
        Robot.load("shr8")
    assert "shr7" in err.value.hint


def test_missing_file(tmp_path):
    with pytest.raises(VfError, match="no file"):
        Robot.load("robots/missing.urdf", base_dir=tmp_path)


@pytest.mark.parametrize("text", [
    "<robot name='x'><link",                                           # not XML
    "<model name='x'/>",                                               # not a <robot>
    "<robot name='x'><link name='a'/><joint name='j' type='revolute'>"
    "<parent link='a'/><child link='nowhere'/></joint></robot>",        # dangling link
], ids=["xml", "root", "semantics"])
def test_malformed_urdf(tmp_path, text):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(VfError, match="malformed URDF"):
        Robot.load(str(path))


def test_unsupported_joint(tmp_path):
    path = tmp_path / "float.urdf"
    path.write_text("<robot name='f'><link name='a'/><link name='b'/><joint name='j' type='floating'>"
                    "<parent link='a'/><child link='b'/></joint></robot>")
    with pytest.raises(VfError, match="not supported"):
        Robot.load(str(path))


def test_unknown_link_suggests_close_names(robot):
    q = np.zeros(robot.nq)
    for call in (lambda: robot.frame_pose(q, "tool_tp"), lambda: robot.frame_jacobian(q, "tool_tp"),
                 lambda: SymbolicKinematics(robot).frame("tool_tp")):
        with pytest.raises(VfError, match="no link 'tool_tp'") as err:
            call()
        assert "did you mean 'tool_tip'" in str(err.value)


@pytest.mark.parametrize("shape", ["short", "long", "matrix"])
def test_wrong_q_length(robot, shape):
    n = robot.nq
    q = {"short": np.zeros(n - 1), "long": np.zeros(n + 1), "matrix": np.zeros((2, n))}[shape]
    with pytest.raises(VfError, match=f"{n} joints"):
        robot.frame_pose(q, "tool_tip")
    with pytest.raises(VfError, match=f"{n} joints"):
        robot.frame_jacobian(q, "tool_tip")


def test_nan_in_q(robot):
    q = np.zeros(robot.nq)
    q[3] = np.nan
    with pytest.raises(VfError, match=robot.joint_names[3]):
        robot.frame_pose(q, "tool_tip")
    with pytest.raises(VfError, match="not finite"):
        robot.frame_jacobian(q, "tool_tip")


def test_bad_offset_and_symbol_shape():
    robot = Robot.load("panda7")
    bad = np.eye(4)
    bad[:3, :3] *= 2
    with pytest.raises(VfError, match="offset"):
        robot.frame_pose(np.zeros(7), "tool_tip", bad)
    with pytest.raises(VfError, match="offset"):
        SymbolicKinematics(robot).frame("tool_tip", np.eye(3))
    with pytest.raises(VfError, match="7 joint symbols"):
        SymbolicKinematics(robot, ca.SX.sym("q", 6))
