"""The fast signed clearance of capsules from a mesh (coal's BVH distance, pseudo-normals for the side) against
brute force over every triangle with the winding number for the side (vfdsl.mesh.brute.signed_clearance): on the
meshes of tasks/anatomy with capsules near, through and far from them, on both sides and both senses, and at the
sharp edge of a wedge, where the side must come from the edge's or the vertex's pseudo-normal, not a face's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from vfdsl.mesh import brute
from vfdsl.mesh.clearance import mesh_clearance
from vfdsl.mesh.load import read_mesh

ANATOMY = Path(__file__).resolve().parent.parent / "tasks" / "anatomy"
RADIUS = 0.001


def _capsules(mesh, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """n capsules (ends a, b) in three kinds: near the surface (an end within 2 mm of a random point of a random
    triangle, at its corners and edges too), through it (ends 0.05 to 3 mm either side along the face's normal)
    and far from it (anywhere in a box three times the mesh's size); one in five is a point (a = b)."""
    corners = mesh.vertices[mesh.triangles]
    which = rng.integers(len(corners), size=n)
    weights = rng.dirichlet([0.3, 0.3, 0.3], size=n)                     # often close to an edge or a corner
    weights[: n // 6] = np.eye(3)[rng.integers(3, size=n // 6)]          # exactly a corner
    on = np.einsum("ni,nij->nj", weights, corners[which])
    normal = np.cross(corners[which, 1] - corners[which, 0], corners[which, 2] - corners[which, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    a = on + rng.uniform(0, 0.002, (n, 1)) * direction
    b = a + rng.uniform(0, 0.04, (n, 1)) * rng.normal(size=(n, 3)) / np.sqrt(3)
    through = np.arange(n) % 3 == 1
    depth = rng.uniform(5e-5, 0.003, (n, 2))
    a[through] = on[through] - depth[through, :1] * normal[through]
    b[through] = on[through] + depth[through, 1:] * normal[through]
    far = np.arange(n) % 3 == 2
    centre, size = mesh.vertices.mean(axis=0), np.ptp(mesh.vertices, axis=0).max()
    a[far] = centre + rng.uniform(-1.5, 1.5, (far.sum(), 3)) * size
    b[far] = a[far] + rng.uniform(0, 0.04, (far.sum(), 1)) * direction[far]
    point = np.arange(n) % 5 == 0
    b[point] = a[point]
    return a, b


def _compare(mesh, a: np.ndarray, b: np.ndarray) -> dict[bool, np.ndarray]:
    query = mesh_clearance(mesh)
    found = {}
    for keep_in in (False, True):
        fast = query(a, b, RADIUS, keep_in)
        slow = np.array([brute.signed_clearance(x, y, RADIUS, mesh.vertices, mesh.triangles, keep_in)
                         for x, y in zip(a, b)])
        worst = int(np.argmax(np.abs(fast - slow)))
        assert np.abs(fast - slow).max() < 1e-10, (keep_in, worst, a[worst], b[worst], fast[worst], slow[worst])
        found[keep_in] = slow
    return found


@pytest.mark.parametrize("name, n", [("channel", 45), ("bone", 45), ("nerve", 90)])
def test_anatomy_clearance_is_brute_force(name, n):
    """Every case occurs in both senses: segments on the free side, on the forbidden side, and through the surface
    (clearance -radius)."""
    mesh = read_mesh(ANATOMY / f"{name}.stl", 1e-3)
    found = _compare(mesh, *_capsules(mesh, np.random.default_rng(len(name)), n))
    for slow in found.values():
        assert (slow < -RADIUS).sum() >= 3 and (slow > -RADIUS).sum() >= 3 and (slow == -RADIUS).sum() >= 3


def test_side_at_a_sharp_edge_is_brute_force(tmp_path):
    """A wedge of 20 deg (a prism 30 mm long): around its sharp edge the two faces' normals are 160 deg apart,
    so for a point just outside the edge one face's normal says inside; points around the edge and its two end
    corners, 0.01 to 1 mm away, inside and outside, and short segments from them, read as the winding number
    says."""
    half = np.radians(10)
    section = [[0, 0], [20 * np.cos(half), 20 * np.sin(half)], [20 * np.cos(half), -20 * np.sin(half)]]
    vertices = [[x, y, z] for z in (0.0, 30.0) for x, y in section]
    faces = [[0, 1, 2], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [2, 0, 3], [2, 3, 5]]
    corners = np.array(vertices)[faces]
    outward = np.einsum("ij,ij->i", np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]),
                        corners.mean(axis=1) - np.mean(vertices, axis=0)) > 0         # (a convex solid)
    wedge = trimesh.Trimesh(vertices, [f if out else f[::-1] for f, out in zip(faces, outward)], process=False)
    assert wedge.is_watertight and wedge.volume > 0
    wedge.export(tmp_path / "wedge.stl")
    mesh = read_mesh(tmp_path / "wedge.stl", 1e-3)
    rng = np.random.default_rng(7)
    n = 120
    along = np.where(np.arange(n) % 4 == 0, rng.choice([0.0, 0.03], n), rng.uniform(0.002, 0.028, n))
    angle = np.where(np.arange(n) % 2 == 0, rng.uniform(-half, half, n), rng.uniform(half, 2 * np.pi - half, n))
    distance = rng.uniform(1e-5, 1e-3, n)
    a = np.stack([distance * np.cos(angle), distance * np.sin(angle), along + rng.uniform(-1e-3, 1e-3, n)], axis=1)
    b = a.copy()
    b[n // 2:] += rng.normal(size=(n - n // 2, 3)) * 2e-4
    found = _compare(mesh, a, b)
    outside = found[False] > -RADIUS                     # the segment outside the wedge
    assert 20 <= outside.sum() <= n - 20


def test_a_mesh_query_is_built_once():
    mesh = read_mesh(ANATOMY / "nerve.stl", 1e-3)
    assert mesh_clearance(mesh) is mesh_clearance(read_mesh(ANATOMY / "nerve.stl", 1e-3))
