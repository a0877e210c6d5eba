"""The simulated optical tracker that scores a run (like the paper's OPTOTRAK, 0.2 mm RMS in 3-D).

It sees two markers per task frame: one at the frame's origin and one ``marker_distance`` up its tool
axis, each with independent Gaussian noise of 3-D RMS ``noise`` (per axis noise / sqrt(3)). The measured
origin is the first marker; the measured tool axis is the unit vector from the first marker to the second,
and the measured rotation is the true one turned by the smallest rotation taking the true axis to the
measured one (the tracker does not see roll about the tool axis). The controller never sees it.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from vfdsl.ir import model as ir
from vfdsl.sim.metrics import Poses


def measure(poses: Poses, task: ir.Task, noise: float, marker_distance: float,
            rng: np.random.Generator) -> Poses:
    """The tracker's reading of every frame at every sample."""
    sigma = noise / math.sqrt(3)
    p_out, R_out = {}, {}
    for frame in task.frames:
        p, R = poses.p[frame.name], poses.R[frame.name]
        axis = poses.axis(frame)
        first = p + sigma * rng.standard_normal(p.shape)
        second = p + marker_distance * axis + sigma * rng.standard_normal(p.shape)
        seen = second - first
        seen /= np.linalg.norm(seen, axis=1, keepdims=True)
        turn = np.cross(axis, seen)
        angle = np.arctan2(np.linalg.norm(turn, axis=1), np.sum(axis * seen, axis=1))
        norm = np.linalg.norm(turn, axis=1, keepdims=True)
        rotvec = np.where(norm > 0, turn / np.where(norm > 0, norm, 1.0), 0.0) * angle[:, None]
        p_out[frame.name] = first
        R_out[frame.name] = Rotation.from_rotvec(rotvec).as_matrix() @ R if len(R) else R
    return Poses(p_out, R_out)
