"""Run-time params: a gizmo per point, line, plane or pose param (and per point of a run-time curve), and how a
new value, from a gizmo, a field or a script, reaches the controller.

A part of :class:`vfdsl.view.app.Viewer`: a value the controller accepts goes into ``self.overrides`` and the
viewer's scene, and the fixtures are redrawn; a refused one is shown and changes nothing.
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel
from scipy.spatial.transform import Rotation

from vfdsl.errors import VfError
from vfdsl.ir import model as ir
from vfdsl.sim import shapes as sh
from vfdsl.view.robot import rotation_to_z
from vfdsl.view.scene import matrix, wxyz


class ParamGizmos:
    """The viewer's run-time params: :meth:`set_param`, and their gizmos in the scene."""

    def set_param(self, name: str, value) -> bool:
        """Give a run-time param a new value (an IR value, or what ``Controller.step`` accepts); the controller
        checks it. False, and the error shown in the GUI, when it is refused."""
        with self.lock:
            candidate = dict(self.overrides)
            try:
                candidate[name] = self._as_value(name, value)
                self.ctrl.problem(self.q, self._zero_inputs(), params=candidate)
            except VfError as err:
                self._show_error(f"param '{name}' refused: {err}")
                self._place_param_gizmos()
                return False
            self.overrides = candidate
            self.scene.set_value(name, candidate[name])
            self._show_error("")
            self._draw_fixtures(force=True)
            self._place_param_gizmos()
            return True

    def _place_param_gizmos(self) -> None:
        """A transform control per point, line, plane or pose param (and per point of a run-time curve)."""
        if self.replay is not None:
            return
        for name in self.ctrl.param_names:
            value = self.scene.values[name]
            R, t = self.scene.to_world(name)
            t = np.asarray(t).reshape(3)
            gizmos = []
            if isinstance(value, ir.PointValue):
                gizmos = [(f"/params/{name}", R @ np.array(value.xyz) + t, np.eye(3), True)]
            elif isinstance(value, (ir.LineValue, ir.PlaneValue)):
                d = value.direction if isinstance(value, ir.LineValue) else value.normal
                gizmos = [(f"/params/{name}", R @ np.array(value.point) + t, rotation_to_z(sh.unit(R @ np.array(d))), False)]
            elif isinstance(value, ir.PoseValue):
                Rp, tp = Rotation.from_euler("xyz", value.rpy).as_matrix(), np.array(value.translation)
                gizmos = [(f"/params/{name}", tp, Rp, False)]
            elif isinstance(value, ir.CurveValue) and value.runtime:
                gizmos = [(f"/params/{name}/p{i}", R @ np.array(p) + t, np.eye(3), True)
                          for i, p in enumerate(value.points)]
            for node, position, rotation, translate_only in gizmos:
                handle = self.nodes.get(node)
                if handle is None:
                    handle = self.server.scene.add_transform_controls(
                        node, scale=0.02, position=position, wxyz=wxyz(rotation), disable_rotations=translate_only,
                        line_width=1.5, opacity=0.8)
                    handle.on_update(lambda e, n=name: self._gizmo_moved(n)
                                     if getattr(e, "phase", "end") == "end" else None)
                    self.nodes[node] = handle
                else:
                    handle.position, handle.wxyz = position, wxyz(rotation)

    def _gizmo_moved(self, name: str) -> None:
        value = self.scene.values[name]
        R, t = self.scene.to_world(name)
        t = np.asarray(t).reshape(3)
        local = lambda x: R.T @ (np.asarray(x) - t)
        node = self.nodes.get(f"/params/{name}")
        if isinstance(value, ir.PointValue):
            new = ir.PointValue(xyz=list(local(node.position)))
        elif isinstance(value, ir.LineValue):
            new = ir.LineValue(point=list(local(node.position)), direction=list(R.T @ (matrix(node.wxyz) @ [0, 0, 1])))
        elif isinstance(value, ir.PlaneValue):
            new = ir.PlaneValue(point=list(local(node.position)), normal=list(R.T @ (matrix(node.wxyz) @ [0, 0, 1])))
        elif isinstance(value, ir.PoseValue):
            new = ir.PoseValue(translation=list(np.asarray(node.position, dtype=float)),
                               rpy=list(Rotation.from_matrix(matrix(node.wxyz)).as_euler("xyz")))
        elif isinstance(value, ir.CurveValue):
            points = [list(local(self.nodes[f"/params/{name}/p{i}"].position)) for i in range(len(value.points))]
            new = ir.CurveValue(degree=value.degree, points=points, runtime=True)
        else:
            return
        self.set_param(name, new)

    def _as_value(self, name: str, value) -> ir.Value:
        """An IR value of param ``name`` from what a GUI gives (lists in SI)."""
        if isinstance(value, BaseModel):                      # already an IR value
            return value
        old = self.scene.values[name]
        v = [float(x) for x in np.asarray(value, dtype=float).reshape(-1)]
        if isinstance(old, ir.PointValue):
            return ir.PointValue(xyz=v)
        if isinstance(old, ir.VectorValue):
            return ir.VectorValue(xyz=v)
        if isinstance(old, ir.DirectionValue):
            return ir.DirectionValue(xyz=v)
        if isinstance(old, ir.ScalarValue):
            return ir.ScalarValue(dimension=old.dimension, value=v[0])
        raise VfError(f"param '{name}': give {old.kind} values through its gizmo")
