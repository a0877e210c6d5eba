"""Shared geometry for the lowerings: polytope directions, plane bases, rotations, in CasADi and numpy.

Polytopes (DESIGN "Conventions"): the n x m sphere polytope has directions
u_ij = [cos a_i cos b_j, cos a_i sin b_j, sin a_i], a_i = 2 pi i / n, b_j = 2 pi j / m (paper eq. 3); the
parametrization repeats directions (the poles; a and pi - a for some n, m), so duplicates are removed
(erratum 3): the paper's 4 x 4 gives the 6 faces of a cube. The n-gon in the plane normal to a unit
vector l has directions R3 [cos a_i, sin a_i, 0], R3 = [v1 v2 l] (paper eq. 8).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

# Guards normalizations in generated code against division by zero (never changes a non-degenerate value
# by more than ~1e-18 relative).
_TINY = 1e-36


def sphere_directions(n: int, m: int) -> np.ndarray:
    """The unique directions of the n x m sphere polytope (rows), in the paper's order of first appearance."""
    a = np.repeat(2 * np.pi * np.arange(1, n + 1) / n, m)
    b = np.tile(2 * np.pi * np.arange(1, m + 1) / m, n)
    u = np.column_stack([np.cos(a) * np.cos(b), np.cos(a) * np.sin(b), np.sin(a)])
    keys = np.round(u, 9) + 0.0                  # + 0.0 folds -0.0 into 0.0; 1e-9 merges rounding twins
    _, first = np.unique(keys, axis=0, return_index=True)
    return u[np.sort(first)]


def polygon_angles(n: int) -> np.ndarray:
    """a_i = 2 pi i / n, i = 1..n (paper eq. 9)."""
    return 2 * math.pi * np.arange(1, n + 1) / n


def skew(v):
    """sk(v): the matrix with sk(v) w = v x w (CasADi)."""
    return ca.vertcat(ca.horzcat(0, -v[2], v[1]), ca.horzcat(v[2], 0, -v[0]), ca.horzcat(-v[1], v[0], 0))


def normalize(v):
    return v / ca.sqrt(ca.sumsqr(v) + _TINY)


def scaled_norm(v):
    """|v| computed from v / max|v_i|, so that neither 1e-160 nor 1e160 components under- or overflow
    (NaN for v = 0)."""
    largest = ca.mmax(ca.fabs(v))
    return largest * ca.norm_2(v / largest)


def normalize_scaled(v):
    """v / |v| for a value given from outside (a run-time direction), scaled first as in :func:`scaled_norm`
    (0 for v = 0)."""
    return normalize(v / (ca.mmax(ca.fabs(v)) + 1e-300))


PARALLEL = 1e-9
"""|l x l'| of two unit axes at most this: parallel or opposite, the cross product has no direction."""


def turn_axis(cross, fallback):
    """cross / |cross| (cross = l x l' of unit axes), or the unit ``fallback`` where the axes are parallel or
    opposite (|cross| <= PARALLEL): then any axis normal to them turns one toward the other."""
    return ca.if_else(ca.norm_2(cross) > PARALLEL, normalize(cross), fallback)


def continued_sine(cross, cosine, fallback):
    """cross = l x l' of unit axes (length sin theta), continued past 90 deg (cosine = l . l' < 0) by length
    2 - sin theta along the same direction (``fallback``, a unit normal to both, where they are opposite): a length
    that increases over [0, 180] deg. The sine falls back to 0 at 180 deg, where rows built on it see no error."""
    return ca.if_else(cosine >= 0, cross, turn_axis(cross, fallback) * (2 - ca.norm_2(cross)))


def plane_basis(l):
    """v1, v2 spanning the plane normal to the unit vector l (paper eq. 8), with l' = x unless l is near x."""
    helper = ca.if_else(ca.fabs(l[0]) < 0.9, ca.DM([1.0, 0.0, 0.0]), ca.DM([0.0, 1.0, 0.0]))
    v1 = normalize(ca.cross(l, helper))
    v2 = normalize(ca.cross(v1, l))
    return v1, v2


def polygon_directions(l, n: int, first=None):
    """The n rows u_i = R3 [cos a_i, sin a_i, 0] of the polygon in the plane normal to l (n x 3, CasADi);
    R3 = [v1 v2 l] from :func:`plane_basis`, or v1 = ``first`` (a unit vector normal to l), v2 = v1 x l."""
    v1, v2 = plane_basis(l) if first is None else (first, normalize(ca.cross(first, l)))
    return ca.vertcat(*[(math.cos(a) * v1 + math.sin(a) * v2).T for a in polygon_angles(n)])


def _rpy_entries(r, p, y, cos, sin) -> list[list]:
    """The rows of Rz(yaw) Ry(pitch) Rx(roll) from the angles and a cos and sin (CasADi's or math's)."""
    cr, sr, cp, sp, cy, sy = cos(r), sin(r), cos(p), sin(p), cos(y), sin(y)
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]


def rpy_matrix(rpy):
    """R = Rz(yaw) Ry(pitch) Rx(roll): URDF's fixed-axis roll-pitch-yaw (works on numbers and CasADi)."""
    return ca.vertcat(*(ca.horzcat(*row) for row in _rpy_entries(rpy[0], rpy[1], rpy[2], ca.cos, ca.sin)))


def _finite_or_nan(f):
    """math's f, NaN (as CasADi's) where math refuses an infinite angle."""
    return lambda x: f(x) if math.isfinite(x) else math.nan


_COS, _SIN = _finite_or_nan(math.cos), _finite_or_nan(math.sin)


def homogeneous(xyz, rpy) -> np.ndarray:
    """The 4x4 numeric transform of a translation and fixed-axis rpy (in floats: no CasADi object per entry)."""
    T = np.eye(4)
    T[:3, :3] = _rpy_entries(*(float(a) for a in rpy), _COS, _SIN)
    T[:3, 3] = xyz
    return T


def rotation(rpy) -> np.ndarray:
    """The numeric 3x3 rotation of a fixed-axis rpy."""
    return np.array(ca.DM(rpy_matrix(ca.DM(list(rpy)))))


GIMBAL = 1e-8
"""cos(pitch) below which :func:`rpy_of` reads a rotation as gimbal-locked (pitch +-90 deg: yaw 0, the roll carrying
the rest; errors ~1e-8 rad either side of it)."""


def rpy_of(R):
    """The fixed-axis rpy of a rotation matrix (inverse of :func:`rpy_matrix`: R = Rz(yaw) Ry(pitch) Rx(roll), pitch in
    [-90, 90] deg; at pitch +-90 deg, yaw = 0): a CasADi column of a symbolic R (a frame's pose captured in the
    tick), a list of floats of a numeric one."""
    symbolic = isinstance(R, (ca.SX, ca.MX))
    M = R if symbolic else ca.DM(np.asarray(R, dtype=float))
    cos_pitch = ca.hypot(M[0, 0], M[1, 0])
    locked = cos_pitch < GIMBAL
    rpy = ca.vertcat(ca.if_else(locked, ca.atan2(-M[1, 2], M[1, 1]), ca.atan2(M[2, 1], M[2, 2])),
                     ca.atan2(-M[2, 0], cos_pitch), ca.if_else(locked, 0, ca.atan2(M[1, 0], M[0, 0])))
    return rpy if symbolic else [float(x) for x in np.array(rpy).ravel()]


def rotation_vector(R):
    """The rotation vector theta * axis of a rotation matrix (CasADi): theta = atan2(|s|, c) with
    s = vee(R - R') / 2 = sin(theta) axis and c = (trace R - 1) / 2 = cos(theta).

    Up to 90 deg (c >= 0) the axis is s / sin(theta) (s itself below sin theta = 1e-12). Past 90 deg sin(theta) falls
    back to 0 (at 180 deg s is 0 and the axis would be lost: a goal half a turn away asked for no rotation), so there
    the axis comes from the symmetric part, (R + R') / 2 - c I = (1 - c) axis axis' (its column of largest diagonal,
    normalized; each diagonal entry is at least 1/3 of 1 - c >= 1 in one column), signed to agree with s (either sign
    at exactly 180 deg: the same rotation)."""
    s = 0.5 * ca.vertcat(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1])
    sin_theta = ca.norm_2(s)
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1)
    theta = ca.atan2(sin_theta, c)
    near = s * ca.if_else(sin_theta > 1e-12, theta / ca.fmax(sin_theta, 1e-12), 1)
    B = 0.5 * (R + R.T) - c * ca.DM.eye(3)
    column = ca.if_else(ca.logic_and(B[0, 0] >= B[1, 1], B[0, 0] >= B[2, 2]), B[:, 0],
                        ca.if_else(B[1, 1] >= B[2, 2], B[:, 1], B[:, 2]))
    axis = normalize(column)
    far = theta * ca.if_else(ca.dot(axis, s) >= 0, axis, -axis)
    return ca.if_else(c >= 0, near, far)


def compose(offset_a, rpy_a, offset_b, rpy_b) -> tuple[list[float], list[float]]:
    """Pose b given in frame a, in a's parent: (t_a + R_a t_b, rpy(R_a R_b)); an offset that overflows comes
    out inf (the caller refuses it)."""
    R_a = rotation(rpy_a)
    with np.errstate(over="ignore", invalid="ignore"):
        offset = np.asarray(offset_a) + R_a @ np.asarray(offset_b)
    return offset.tolist(), rpy_of(R_a @ rotation(rpy_b))
