"""The shipped robots: Panda and the PSM against their published DH tables (the PSM's mechanical remote center),
Steady-Hand conventions, metadata, loading."""

from __future__ import annotations

import shutil

import numpy as np
import pinocchio as pin
import pytest

from vfdsl.errors import VfError
from vfdsl.kinematics import Robot, shipped_robots
from vfdsl.kinematics.robot import ROBOTS_DIR

# Franka Panda, published modified (Craig) DH table: (a, d, alpha) per joint, then the flange.
PANDA_DH = [(0.0, 0.333, 0.0), (0.0, 0.0, -np.pi / 2), (0.0, 0.316, np.pi / 2), (0.0825, 0.0, np.pi / 2),
            (-0.0825, 0.384, -np.pi / 2), (0.0, 0.0, np.pi / 2), (0.088, 0.0, np.pi / 2)]
PANDA_FLANGE_D = 0.107
PANDA_TCP_D = 0.1034
PANDA_LOWER = [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]
PANDA_UPPER = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]
PANDA_VELOCITY = [2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100]


def rot_x(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rot_z(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def trans(x=0.0, z=0.0):
    T = np.eye(4)
    T[0, 3], T[2, 3] = x, z
    return T


def panda_dh(q) -> list[np.ndarray]:
    """World poses of link1..link7, flange and tool_tip: T_i = T_{i-1} RotX(alpha) TransX(a) RotZ(q_i) TransZ(d)."""
    T, poses = np.eye(4), []
    for (a, d, alpha), qi in zip(PANDA_DH, q):
        T = T @ rot_x(alpha) @ trans(x=a) @ rot_z(qi) @ trans(z=d)
        poses.append(T)
    poses.append(poses[-1] @ trans(z=PANDA_FLANGE_D))
    poses.append(poses[-1] @ trans(z=PANDA_TCP_D))
    return poses


@pytest.fixture(scope="module")
def panda() -> Robot:
    return Robot.load("panda7")


@pytest.fixture(scope="module")
def shr() -> Robot:
    return Robot.load("shr7")


def within_limits(robot: Robot, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(robot.lower, robot.upper, size=(n, robot.nq))


# --- panda7 ---------------------------------------------------------------------------------------------

def test_panda_urdf_matches_direct_dh_product(panda):
    links = [f"link{i}" for i in range(1, 8)] + ["flange", "tool_tip"]
    for q in within_limits(panda, 200, seed=10):
        for link, T in zip(links, panda_dh(q)):
            p, R = panda.frame_pose(q, link)
            np.testing.assert_allclose(p, T[:3, 3], rtol=0, atol=1e-12, err_msg=link)
            np.testing.assert_allclose(R, T[:3, :3], rtol=0, atol=1e-12, err_msg=link)


def test_panda_published_limits(panda):
    assert panda.joint_names == [f"joint{i}" for i in range(1, 8)]
    assert panda.joint_types == ["revolute"] * 7
    np.testing.assert_array_equal(panda.lower, PANDA_LOWER)
    np.testing.assert_array_equal(panda.upper, PANDA_UPPER)
    np.testing.assert_array_equal(panda.velocity_limit, PANDA_VELOCITY)
    assert panda.resolution is None
    assert panda.tool_axis["tool_tip"] == "z"


def test_panda_tool_tip_approach_axis_points_away_from_flange(panda):
    for q in within_limits(panda, 20, seed=11):
        p_flange, _ = panda.frame_pose(q, "flange")
        p_tip, R_tip = panda.frame_pose(q, "tool_tip")
        np.testing.assert_allclose(p_tip - p_flange, PANDA_TCP_D * R_tip[:, 2], atol=1e-14)


# --- shr7 -----------------------------------------------------------------------------------------------

RCM_HEIGHT = 0.3


def test_shr_joints_and_limits(shr):
    assert shr.joint_names == ["x", "y", "z", "rcm_a", "rcm_b", "roll", "insert"]
    assert shr.joint_types == ["prismatic"] * 3 + ["revolute"] * 3 + ["prismatic"]
    np.testing.assert_allclose(shr.upper, [0.06, 0.06, 0.05, np.pi / 3, np.pi / 3, np.radians(170), 0.15])
    np.testing.assert_allclose(shr.lower, [-0.06, -0.06, -0.05, -np.pi / 3, -np.pi / 3, -np.radians(170), -0.05])
    np.testing.assert_allclose(shr.velocity_limit, [0.02] * 3 + [np.radians(30)] * 3 + [0.02])
    np.testing.assert_allclose(shr.resolution, [1e-5] * 3 + [1e-4] * 3 + [1e-5])
    assert shr.tool_axis["tool_tip"] == "z"
    assert shr.description


def test_shr_home_pose(shr):
    q = np.zeros(7)
    p_tip, R_tip = shr.frame_pose(q, "tool_tip")
    p_rcm, R_rcm = shr.frame_pose(q, "rcm")
    np.testing.assert_allclose(p_rcm, [0, 0, RCM_HEIGHT], atol=1e-14)
    np.testing.assert_allclose(p_tip, p_rcm, atol=1e-14)
    np.testing.assert_allclose(R_tip, np.eye(3), atol=1e-14)  # tool axis (z) is world +z
    p_holder, R_holder = shr.frame_pose(q, "tool_holder")
    np.testing.assert_allclose(p_holder, p_tip + [0, 0, 0.1], atol=1e-14)
    np.testing.assert_allclose(R_holder, R_tip, atol=1e-14)


def test_shr_rcm_link_translates_with_stage_and_never_rotates(shr):
    for q in within_limits(shr, 50, seed=12):
        p, R = shr.frame_pose(q, "rcm")
        np.testing.assert_allclose(p, [q[0], q[1], RCM_HEIGHT + q[2]], atol=1e-14)
        np.testing.assert_allclose(R, np.eye(3), atol=1e-14)


def test_shr_rcm_axes(shr):
    """rcm_a turns about world x, rcm_b about the y axis that rcm_a produced."""
    a, b = 0.4, -0.3
    _, R = shr.frame_pose([0, 0, 0, a, 0, 0, 0], "tool_tip")
    np.testing.assert_allclose(R[:, 2], [0, -np.sin(a), np.cos(a)], atol=1e-14)
    _, R = shr.frame_pose([0, 0, 0, a, b, 0, 0], "tool_tip")
    np.testing.assert_allclose(R, pin.rpy.rpyToMatrix(a, 0, 0) @ pin.rpy.rpyToMatrix(0, b, 0), atol=1e-14)


def test_shr_insertion_moves_tip_down_the_tool_axis(shr):
    assert shr.upper[6] >= 0.010 and shr.lower[6] < 0  # reaches 10 mm below the RCM and can retract
    for q in within_limits(shr, 50, seed=13):
        q0 = q.copy()
        q0[6] = 0.0
        p0, R0 = shr.frame_pose(q0, "tool_tip")
        p_rcm, _ = shr.frame_pose(q0, "rcm")
        np.testing.assert_allclose(p0, p_rcm, atol=1e-14)  # tip at the RCM when insert = 0
        p, R = shr.frame_pose(q, "tool_tip")
        np.testing.assert_allclose(p, p0 - q[6] * R0[:, 2], atol=1e-14)
        np.testing.assert_allclose(R, R0, atol=1e-14)


def test_shr_rcm_stays_on_the_tool_axis(shr):
    for q in within_limits(shr, 200, seed=14):
        p_tip, R_tip = shr.frame_pose(q, "tool_tip")
        p_rcm, _ = shr.frame_pose(q, "rcm")
        axis = R_tip[:, 2]
        d = p_rcm - p_tip
        np.testing.assert_allclose(d - (d @ axis) * axis, 0, atol=1e-14)  # distance from the line
        # tool axis points from the tip toward the handle: the RCM is above the tip when inserted
        assert d @ axis == pytest.approx(q[6], abs=1e-14)


def test_shr_jacobian_keeps_rcm_still(shr):
    """At the tool point that sits at the RCM, rcm_a, rcm_b and roll give no velocity; insert slides it along -z."""
    for q in within_limits(shr, 20, seed=15):
        offset = np.eye(4)
        offset[2, 3] = q[6]  # the tool-axis point that sits at the RCM
        J = shr.frame_jacobian(q, "tool_tip", offset)
        np.testing.assert_allclose(J[:3, 3:6], 0, atol=1e-14)
        np.testing.assert_allclose(J[:3, :3], np.eye(3), atol=1e-14)
        np.testing.assert_allclose(J[:3, 6], -shr.frame_pose(q, "tool_tip")[1][:, 2], atol=1e-14)


# --- psm6 -----------------------------------------------------------------------------------------------
# The dVRK's classic PSM with a large needle driver, modified DH (alpha, a, theta0, d0) per joint, then the control
# point: the published table, written out here again (not read from the URDF) for an independent product.
PSM_DH = [(np.pi / 2, 0.0, np.pi / 2, 0.0), (-np.pi / 2, 0.0, -np.pi / 2, 0.0), (np.pi / 2, 0.0, 0.0, -0.4318),
          (0.0, 0.0, 0.0, 0.4162), (-np.pi / 2, 0.0, -np.pi / 2, 0.0), (-np.pi / 2, 0.0091, -np.pi / 2, 0.0)]
PSM_PRISMATIC = 2
PSM_TIP = np.array([[0, -1, 0, 0], [0, 0, 1, 0.0102], [-1, 0, 0, 0], [0, 0, 0, 1.0]])


def psm_dh(q) -> tuple[np.ndarray, np.ndarray]:
    """World poses of the roll link (the shaft) and of tool_tip, by the DH product."""
    T, roll = np.eye(4), None
    for i, ((alpha, a, theta0, d0), qi) in enumerate(zip(PSM_DH, q)):
        theta, d = (theta0, d0 + qi) if i == PSM_PRISMATIC else (theta0 + qi, d0)
        T = T @ rot_x(alpha) @ trans(x=a) @ rot_z(theta) @ trans(z=d)
        roll = T if i == 3 else roll
    return roll, T @ PSM_TIP


@pytest.fixture(scope="module")
def psm() -> Robot:
    return Robot.load("psm6")


def test_psm_urdf_matches_the_published_dh_product(psm):
    assert psm.joint_names == ["outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch",
                               "outer_wrist_yaw"]
    for q in within_limits(psm, 100, seed=21):
        roll, tip = psm_dh(q)
        for name, T in (("tool_roll", roll), ("tool_tip", tip)):
            p, R = psm.frame_pose(q, name)
            np.testing.assert_allclose(p, T[:3, 3], atol=1e-14)
            np.testing.assert_allclose(R, T[:3, :3], atol=1e-14)


def test_psm_shaft_passes_through_the_rcm_which_never_moves(psm):
    """The mechanical remote center: the shaft's line (tool_roll's z) passes through the root link `rcm` at every
    configuration, and the shaft point at the RCM moves only along the shaft (the Jacobian at that point)."""
    for q in within_limits(psm, 100, seed=22):
        p, R = psm.frame_pose(q, "tool_roll")
        axis = R[:, 2]
        np.testing.assert_allclose(-p - (-p @ axis) * axis, 0, atol=1e-15)       # the RCM (origin) on the line
        depth = -p @ axis                            # the RCM's coordinate along the shaft from the roll frame
        assert depth == pytest.approx(-(q[2] - 0.4318 + 0.4162), abs=1e-15)
        offset = np.eye(4)
        offset[2, 3] = depth
        v = psm.frame_jacobian(q, "tool_roll", offset)[:3]
        lateral = v - np.outer(axis, axis) @ v
        np.testing.assert_allclose(lateral, 0, atol=1e-14)


def test_psm_tip_below_the_rcm_along_the_jaws_at_zero(psm):
    for d in (0.0, 0.1, 0.24):
        p, R = psm.frame_pose(np.array([0, 0, d, 0, 0, 0.0]), "tool_tip")
        np.testing.assert_allclose(p, [0, 0, -(d + 0.0037)], atol=1e-15)
        np.testing.assert_allclose(R[:, 2], [0, 0, -1], atol=1e-15)
    assert psm.tool_axis == {"tool_tip": "z", "tool_roll": "z"} and psm.resolution is None
    np.testing.assert_allclose(psm.lower, [-1.5, -0.9, 0.0, -4.538, -1.396, -1.396])
    np.testing.assert_allclose(psm.velocity_limit, [1.0, 1.0, 0.2, 8.0, 8.0, 8.0])


def test_a_task_on_the_psm_tracks_the_hand_through_its_remote_center(tmp_path):
    """A hands-on task on psm6 compiles and runs: the tip follows a force, the shaft still through the RCM."""
    import vfdsl
    (tmp_path / "psm.vf").write_text('task psm\nunits mm, deg\nrobot psm = urdf "psm6"\n'
                                     'frame tip = psm.link("tool_tip")\ninput f : force\n'
                                     'minimize track(tip, f, gain = 2 mm/s/N)\nminimize damping() weight 1e-6\n'
                                     'require joint_limits()\nrequire joint_speed()\n')
    (tmp_path / "psm.yaml").write_text("start: [0, 0, 100 mm, 0, 0, 0]\nperiod: 1 ms\n")
    task = vfdsl.load(tmp_path / "psm.vf")
    ctrl = vfdsl.compile(task, backend="interpreted")
    robot = Robot.load("psm6")
    q = np.array(task.start)
    start = robot.frame_pose(q, "tool_tip")[0]
    for _ in range(200):
        q = q + ctrl.step(q, {"f": [3.0, 0.0, 0.0]})
    moved = robot.frame_pose(q, "tool_tip")[0] - start
    assert moved[0] == pytest.approx(200 * 1e-3 * 2e-3 * 3.0, rel=0.05) and abs(moved[1]) < 1e-5
    p, R = robot.frame_pose(q, "tool_roll")
    np.testing.assert_allclose(-p - (-p @ R[:, 2]) * R[:, 2], 0, atol=1e-15)


@pytest.mark.parametrize("name", ["shr7", "panda7", "psm6"])
def test_pinocchio_dynamics_are_well_posed(name):
    robot = Robot.load(name)
    data = robot.model.createData()
    q = robot.to_pinocchio(within_limits(robot, 1, seed=16)[0])
    M = pin.crba(robot.model, data, q)
    assert np.all(np.isfinite(M)) and np.all(np.linalg.eigvalsh((M + M.T) / 2) > 0)


# --- loading and sidecars -------------------------------------------------------------------------------

def test_shipped_names_and_paths(tmp_path):
    assert shipped_robots() == ["panda7", "psm6", "shr7"]
    for spec, base in [("shr7", None), ("shr7.urdf", None), (str(ROBOTS_DIR / "shr7.urdf"), None),
                       ("shr7.urdf", tmp_path)]:
        robot = Robot.load(spec, base_dir=base)
        assert robot.name == "shr7" and robot.urdf_path.resolve() == (ROBOTS_DIR / "shr7.urdf").resolve()


def test_user_urdf_relative_to_base_dir_shadows_shipped(tmp_path):
    (tmp_path / "robots").mkdir()
    shutil.copy(ROBOTS_DIR / "panda7.urdf", tmp_path / "robots" / "mine.urdf")
    robot = Robot.load("robots/mine.urdf", base_dir=tmp_path)
    assert robot.urdf_path == tmp_path / "robots" / "mine.urdf"
    assert robot.resolution is None and robot.tool_axis == {} and robot.description == ""
    shutil.copy(ROBOTS_DIR / "panda7.urdf", tmp_path / "shr7.urdf")
    assert Robot.load("shr7.urdf", base_dir=tmp_path).name == "panda7"


@pytest.mark.parametrize("sidecar, message", [
    ("resolution: {joint1: 1.0e-4}", "every joint"),
    ("tool_axis: {tool_tipp: z}", "did you mean 'tool_tip'"),
    ("tool_axis: {tool_tip: w}", "x, y or z"),
    ("colour: red", "unknown key"),
    ("resolution: [1, 2", "not valid YAML"),
], ids=["partial-resolution", "unknown-link", "bad-axis", "unknown-key", "yaml"])
def test_bad_sidecar(tmp_path, sidecar, message):
    shutil.copy(ROBOTS_DIR / "panda7.urdf", tmp_path / "arm.urdf")
    (tmp_path / "arm.yaml").write_text(sidecar)
    with pytest.raises(VfError, match=message):
        Robot.load("arm.urdf", base_dir=tmp_path)
