"""The signed clearance of capsules from a mesh, fast: what ``vfdsl simulate`` scores a mesh fixture with.

For a capsule (segment a b, radius r) and a closed mesh, with d the distance from the segment to the surface:

    clearance = d - r     the segment on the free side (inside the mesh for keep_in, outside otherwise)
              = -d - r    the segment on the forbidden side (an end through the surface counts through)

d comes from coal's BVH distance (a capsule of radius 0, i.e. the segment, against the triangles); coal also
gives the pair that attains it: x on the segment and the triangle whose point c is nearest to x. When d > 0
the segment does not cross the surface, so both ends lie on x's side, read from the angle-weighted
pseudo-normal n of c's feature (face, edge or vertex: :func:`vfdsl.mesh.tables.pseudo_normals`): x is
outside when (x - c) . n > 0 (Baerentzen & Aanaes 2005). When d = 0 the side does not change the value.
On a closed, consistently oriented mesh this is :func:`vfdsl.mesh.brute.signed_clearance` (the reference the
tests compare it with), whose side is the winding number; on an open mesh the side is that of the nearest
surface by its orientation, as the controller's rows read it.
"""

from __future__ import annotations

import functools

import coal
import numpy as np

from vfdsl.mesh.brute import point_triangles
from vfdsl.mesh.load import MeshData
from vfdsl.mesh.tables import pseudo_normals

CHUNK = 500
"""Capsules measured between two progress reports (about 0.01 to 0.1 s)."""
TOUCH = 1e-12
"""m: a segment this close to the surface touches it (its side no longer matters: -d - r = d - r to within it)."""
GJK_TOLERANCE = 1e-12
"""coal's GJK stopping tolerance (its default, 1e-6, leaves errors of 0.5 um, and calls a segment 0.5 um from the
surface touching)."""
ON_EDGE = 1e-9
"""A barycentric coordinate of c below this puts c on the edge opposite that corner (two: on the third corner)."""


class MeshClearance:
    """One mesh's BVH (coal) and pseudo-normals, built once; called with capsules, gives their clearances."""

    def __init__(self, mesh: MeshData):
        self.vertices, self.triangles = mesh.vertices, mesh.triangles
        self.bvh = coal.BVHModelOBBRSS()
        self.bvh.beginModel(len(mesh.triangles), len(mesh.vertices))
        self.bvh.addVertices(np.ascontiguousarray(mesh.vertices, dtype=float))
        self.bvh.addTriangles(np.ascontiguousarray(mesh.triangles, dtype=np.int64))
        self.bvh.endModel()
        self.faces, edges, self.vertex_normals = pseudo_normals(mesh.vertices, mesh.triangles)
        self.edges = edges.reshape(-1, 3, 3)                  # T x edge (0,1), (1,2), (2,0) x 3

    def __call__(self, a: np.ndarray, b: np.ndarray, radius: float, keep_in: bool, progress=None) -> np.ndarray:
        """Clearances (N) of the capsules from a[i] to b[i] (N x 3 each, in the mesh's frame) of ``radius``;
        ``progress(n)``, when given, is called after every CHUNK capsules (n of them) and at the end."""
        a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
        d, x, t = self.nearest(a, b, progress)
        inside = self.inside(x, t, d > TOUCH)
        wrong = inside != keep_in
        return np.where(wrong & (d > TOUCH), -d, d) - radius

    def nearest(self, a: np.ndarray, b: np.ndarray, progress=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each segment a[i] b[i]: its distance to the surface (0 when it crosses it), the segment's point
        that attains it and the triangle nearest to that point; ``progress`` as in :meth:`__call__`."""
        n = len(a)
        axis = b - a
        length = np.linalg.norm(axis, axis=1)
        rotations = _rotations_to(axis, length)
        centres = 0.5 * (a + b)
        request, result, identity, place = coal.DistanceRequest(), coal.DistanceResult(), coal.Transform3s(), \
            coal.Transform3s()
        request.gjk_tolerance = GJK_TOLERANCE
        d, x, t = np.empty(n), np.empty((n, 3)), np.empty(n, dtype=np.int64)
        shape, half = coal.Capsule(0.0, 0.0), 0.0
        for i in range(n):
            if 0.5 * length[i] != half:
                half = shape.halfLength = 0.5 * float(length[i])
                shape.computeLocalAABB()
            place.setRotation(rotations[i])
            place.setTranslation(centres[i])
            result.clear()
            d[i] = coal.distance(self.bvh, identity, shape, place, request, result)
            x[i], t[i] = result.getNearestPoint2(), result.b1        # (the segment's point; the mesh's triangle)
            if progress is not None and (i + 1) % CHUNK == 0:
                progress(CHUNK)
        if progress is not None and n % CHUNK:
            progress(n % CHUNK)
        return np.maximum(d, 0.0), x, t

    def inside(self, x: np.ndarray, t: np.ndarray, off: np.ndarray) -> np.ndarray:
        """Whether each point x[i] (where ``off``: not on the surface) is inside the mesh, by the pseudo-normal of
        its nearest feature on triangle t[i]."""
        out = np.zeros(len(x), dtype=bool)
        rows = np.flatnonzero(off)
        if not len(rows):
            return out
        x, t = x[rows], t[rows]
        corners = self.vertices[self.triangles[t]]                            # n x 3 x 3
        c = point_triangles(x, corners)
        weights = _barycentric(c, corners)
        small = weights < ON_EDGE
        normal = self.faces[t].copy()
        for i in range(3):            # one coordinate ~0: on the edge opposite corner i, edge (i+1, i+2)
            on_edge = small[:, i] & (small.sum(axis=1) == 1)
            normal[on_edge] = self.edges[t[on_edge], (i + 1) % 3]
            on_corner = ~small[:, i] & (small.sum(axis=1) == 2)
            normal[on_corner] = self.vertex_normals[self.triangles[t[on_corner], i]]
        out[rows] = np.einsum("ij,ij->i", x - c, normal) < 0
        return out


@functools.lru_cache(maxsize=16)
def mesh_clearance(mesh: MeshData) -> MeshClearance:
    """The clearance query of ``mesh``, built once per mesh (read_mesh returns one object per file and unit)."""
    return MeshClearance(mesh)


def _rotations_to(axis: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Rotations (N x 3 x 3) whose z axis is each row of ``axis`` (of ``length``; any for a point)."""
    z = np.where(length[:, None] > 0, axis / np.where(length > 0, length, 1.0)[:, None], [0.0, 0.0, 1.0])
    helper = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=2)


def _barycentric(c: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (n x 3) of points c in their triangles (n x 3 x 3)."""
    e1, e2, r = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0], c - corners[:, 0]
    d11, d12, d22 = (np.einsum("ij,ij->i", u, v) for u, v in ((e1, e1), (e1, e2), (e2, e2)))
    r1, r2 = np.einsum("ij,ij->i", r, e1), np.einsum("ij,ij->i", r, e2)
    det = d11 * d22 - d12 * d12
    v, w = (d22 * r1 - d12 * r2) / det, (d11 * r2 - d12 * r1) / det
    return np.stack([1.0 - v - w, v, w], axis=1)
