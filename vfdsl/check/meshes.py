"""Mesh fixtures (``outside_mesh``, ``inside_mesh``): the mesh itself, the clearance at the start, and the margin
against the error of one tick's linearization.

- VF901 mesh-start-clearance: the tool's clearance at the start, measured by brute force over every triangle
  (:mod:`vfdsl.mesh.brute`; the side from the query's pseudo-normals): an error through the surface, a warning
  inside the margin, else a note with the number.
- VF902 mesh-open: ``inside_mesh`` needs a closed mesh (every edge shared by two triangles): error; an open mesh
  for ``outside_mesh`` is a note (its side is the file's orientation).
- VF903 mesh-degenerate: triangles of zero area or repeated, dropped when the mesh was read (warning).
- VF904 mesh-inverted: a closed mesh whose normals point inward (negative volume) or whose neighbours disagree
  on orientation: the free side is wrong somewhere (error).
- VF905 mesh-extent: an extent plausible but unusual for anatomy (under 2 mm or over 0.4 m; outside
  [0.5 mm, 2 m] the front end refuses it): a unit slip? (warning).
- VF906 mesh-margin-linearization: one tick moves the tool's segment by at most v dt, v = sum_j |J_j| qdot_max_j
  at the start (the joints' speed limits, for each end of the segment; a hard `speed` limit on that end's frame
  when it is lower: the circumradius of its polytope times its speed), and the rows then hold the clearance
  to within e = 0.48 v dt + (v dt)^2 / (2 rho) (:mod:`vfdsl.compiler.mesh_rows`), rho the smallest radius of
  curvature of the mesh's concave edges as seen from the free side (edge length / dihedral angle, mean of the two
  triangles' edges). A margin below e: warning (the tool may touch the surface); a reach below v dt: warning.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation

from vfdsl.check.kinematics import frame_jacobian, frame_pose
from vfdsl.primitives.bounds import constraint_geometry
from vfdsl.check.report import Finding, Severity
from vfdsl.compiler.context import ParamLayout, ParamReader
from vfdsl.compiler.mesh_rows import K
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh import brute
from vfdsl.mesh.external import mesh_query
from vfdsl.mesh.load import MeshData, read_mesh

PRIMITIVES = ("outside_mesh", "inside_mesh")
UNUSUAL_EXTENT = (2e-3, 0.4)
MERGED = 0.48


def _subject(c: ir.Constraint) -> str:
    return f"{c.primitive}({c.frame}) at {c.span.file}:{c.span.line}"


def concave_radius(mesh: MeshData, keep_in: bool) -> float:
    """The smallest radius of curvature of the mesh's edges that are concave seen from the free side (inf when
    none is): edge length / dihedral angle, over edges shared by two triangles."""
    v, t = mesh.vertices, mesh.triangles
    normals = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    faces = np.tile(np.arange(len(t)), 3)
    order = np.lexsort(np.sort(edges, axis=1).T[::-1])
    keys = np.sort(edges, axis=1)[order]
    pair = np.flatnonzero(np.all(keys[1:] == keys[:-1], axis=1))
    f1, f2 = faces[order][pair], faces[order][pair + 1]
    angle = np.arccos(np.clip(np.sum(normals[f1] * normals[f2], axis=1), -1, 1))
    # concave from the outside: the other triangle's far corner lies on the outer side of this one's plane
    centre2 = v[t[f2]].mean(axis=1)
    outward = np.sum((centre2 - v[t[f1, 0]]) * normals[f1], axis=1) > 0
    concave = outward != keep_in
    length = np.linalg.norm(v[keys[pair, 0]] - v[keys[pair, 1]], axis=1)
    size = np.sqrt(0.5 * (np.linalg.norm(np.cross(v[t[f1, 1]] - v[t[f1, 0]], v[t[f1, 2]] - v[t[f1, 0]]), axis=1)))
    keep = concave & (angle > 1e-6)
    if not keep.any():
        return float("inf")
    return float(np.min(np.maximum(length, size)[keep] / angle[keep]))


def analyse(task: ir.Task, robot: Robot, q, period: float, figures: dict) -> list[Finding]:
    findings: list[Finding] = []
    reader = ParamReader(task.params, ca.DM(ParamLayout(task.params).defaults))
    for c in task.constraints:
        if c.primitive not in PRIMITIVES:
            continue
        keep_in = c.primitive == "inside_mesh"
        decl = task.param(c.args["mesh"].name)
        mesh = read_mesh(decl.value.file, decl.value.unit)
        subject, span = _subject(c), c.span
        findings += _validity(mesh, keep_in, decl, subject, span)
        margin, radius, reach = (float(reader.scalar(c.args[k])) for k in ("margin", "radius", "reach"))
        R, t = np.eye(3), np.zeros(3)
        if decl.frame is not None:
            pose = task.param(decl.frame).value
            R, t = Rotation.from_euler("xyz", pose.rpy).as_matrix(), np.array(pose.translation)
        a_frame, b_frame = task.frame(c.frame), task.frame(c.args["shaft"].name)
        a, b = (R.T @ (frame_pose(robot, f, q)[0] - t) for f in (a_frame, b_frame))
        d = brute.segment_distances(a, b, mesh.vertices, mesh.triangles).min()
        first = float(np.array(mesh_query(mesh, K).function(a, b, [np.inf, -1.0 if keep_in else 1.0])[0]).ravel()[0])
        clearance = (d if first >= 0 else -d) - radius
        figures.setdefault("mesh_clearance_at_start", {})[subject] = clearance
        words = f"the tool's clearance from '{decl.name}' at the start is {clearance * 1e3:.3f} mm (margin {margin * 1e3:g} mm)"
        if clearance < 0:
            findings.append(Finding("mesh-start-clearance", Severity.ERROR, words + ": through the surface", span,
                                    "start the tool on the free side, or check the mesh's pose and units",
                                    subject, {"clearance": clearance, "margin": margin}))
        elif clearance < margin:
            findings.append(Finding("mesh-start-clearance", Severity.WARNING, words + ": inside the margin; the "
                                    "first ticks push it out", span, None, subject,
                                    {"clearance": clearance, "margin": margin}))
        else:
            findings.append(Finding("mesh-start-clearance", Severity.NOTE, words, span, None, subject,
                                    {"clearance": clearance, "margin": margin}))
        speed = max(_speed(task, robot, f, q, reader) for f in (a_frame, b_frame))
        step = speed * period
        rho = concave_radius(mesh, keep_in)
        bound = MERGED * step + (step ** 2 / (2 * rho) if np.isfinite(rho) else 0.0)
        figures.setdefault("mesh_linearization_bound", {})[subject] = bound
        data = {"step": step, "bound": bound, "radius_of_curvature": rho, "margin": margin, "reach": reach}
        if margin < bound:
            findings.append(Finding(
                "mesh-margin-linearization", Severity.WARNING,
                f"one tick at the joints' speed limits moves the tool up to {step * 1e3:.3g} mm; the rows then hold "
                f"the clearance to within {bound * 1e3:.3g} mm, more than the margin of {margin * 1e3:g} mm", span,
                f"a margin of at least {bound * 1e3:.3g} mm, a speed limit, or a shorter period", subject, data))
        if reach < step:
            findings.append(Finding(
                "mesh-margin-linearization", Severity.WARNING,
                f"reach {reach * 1e3:g} mm is less than one tick's motion ({step * 1e3:.3g} mm): a feature may be "
                f"hit before it gets a row", span, f"reach = {step * 1e3:.3g} mm or more", subject, data))
    return findings


def _speed(task: ir.Task, robot: Robot, frame: ir.FrameDecl, q, reader: ParamReader) -> float:
    """A bound of the frame's speed: sum_j |J_j| qdot_max_j, or a hard `speed` limit on it when lower (its
    polytope's circumradius times the stated speed: what its rows admit)."""
    bound = float(np.abs(frame_jacobian(robot, frame, q)[:3]).sum(axis=0) @ robot.velocity_limit)
    for c in task.constraints:
        if c.primitive == "speed" and c.frame == frame.name and not c.soft:
            bound = min(bound, constraint_geometry(c).circumradius * float(reader.scalar(c.args["max"])))
    return bound


def _validity(mesh: MeshData, keep_in: bool, decl: ir.ParamDecl, subject: str, span) -> list[Finding]:
    out = []
    name = f"mesh '{decl.name}' ({len(mesh.triangles)} triangles)"
    if not mesh.watertight:
        out.append(Finding("mesh-open", Severity.ERROR if keep_in else Severity.NOTE,
                           f"{name} is not closed: some edge is not shared by exactly two triangles"
                           + ("; inside_mesh needs a closed volume" if keep_in else
                              "; its free side is where its normals point"), span,
                           "close the mesh (fill its holes)" if keep_in else None, subject))
    elif mesh.volume < 0 or not mesh.winding_consistent:
        why = "its normals point inward (negative volume)" if mesh.winding_consistent else \
            "neighbouring triangles disagree on its orientation"
        out.append(Finding("mesh-inverted", Severity.ERROR, f"{name}: {why}, so the free side is wrong", span,
                           "reorient the mesh's triangles (trimesh: mesh.fix_normals())", subject))
    if mesh.degenerate or mesh.duplicate:
        out.append(Finding("mesh-degenerate", Severity.WARNING,
                           f"{name}: {mesh.degenerate} degenerate and {mesh.duplicate} repeated triangles were "
                           "dropped", span, "clean the mesh where it was exported", subject,
                           {"degenerate": mesh.degenerate, "duplicate": mesh.duplicate}))
    low, high = UNUSUAL_EXTENT
    if not low <= mesh.extent <= high:
        out.append(Finding("mesh-extent", Severity.WARNING,
                           f"{name} spans {mesh.extent * 1e3:.4g} mm, one file unit read as {decl.value.unit:g} m: "
                           "unusual for anatomy", span, "is mesh(unit = ...) right?", subject,
                           {"extent": mesh.extent}))
    return out
