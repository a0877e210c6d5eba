"""The proximity query's tables (vfdsl/mesh/tables.py): the BVH holds every triangle once, in oriented boxes that hold
their triangles, split so that the depth stays bounded, on real, flat, repeated and tiny meshes; and the query's answer
does not depend on the BVH: the same bits whatever the order of the triangles in the file (ties of the nearest feature,
which triangles that share an edge give at the same distance, included)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from vfdsl.compiler.mesh_rows import K, REACH
from vfdsl.mesh import external, tables
from vfdsl.mesh.external import mesh_query
from vfdsl.mesh.load import read_mesh
from vfdsl.mesh.tables import LEAF, SHARE, build_tables, pseudo_normals

CHANNEL = Path(__file__).resolve().parent.parent / "tasks" / "anatomy" / "channel.stl"


def _grid(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A flat n x n grid of squares (2 n^2 coplanar triangles), tilted out of the world's planes."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    flat = np.column_stack([i.ravel(), j.ravel(), np.zeros(i.size)]) * 1e-3
    c, s = math.cos(0.3), math.sin(0.3)
    vertices = flat @ np.array([[1, 0, 0], [0, c, s], [0, -s, c]])
    corner = (i[:-1, :-1] * (n + 1) + j[:-1, :-1]).ravel()
    triangles = np.concatenate([np.column_stack([corner, corner + n + 1, corner + 1]),
                                np.column_stack([corner + 1, corner + n + 1, corner + n + 2])])
    return vertices, triangles


def _meshes():
    channel = read_mesh(CHANNEL, 1e-3)
    rng = np.random.default_rng(3)
    soup = rng.uniform(-0.01, 0.01, (300, 3))
    one = np.array([[0.0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0]])
    return {
        "channel": (channel.vertices, channel.triangles),
        "flat grid": _grid(12),
        "soup": (soup, np.arange(300).reshape(100, 3)),
        "one triangle": (one, np.array([[0, 1, 2]])),
        "nine repeats": (one, np.tile([[0, 1, 2]], (9, 1))),             # every centroid the same
    }


MESHES = _meshes()


def _ranges(nodes: np.ndarray) -> dict[int, tuple[int, int]]:
    """Each node's triangles (first, count), from its leaves: a node's children hold adjacent runs."""
    ranges: dict[int, tuple[int, int]] = {}

    def visit(node: int) -> tuple[int, int]:
        left, right = nodes[node]
        if left < 0:
            ranges[node] = (-1 - int(left), int(right))
        else:
            (f1, n1), (f2, n2) = visit(int(left)), visit(int(right))
            assert f1 + n1 == f2
            ranges[node] = (f1, n1 + n2)
        return ranges[node]

    visit(0)
    return ranges


def _depth(nodes: np.ndarray, node: int = 0) -> int:
    left, right = nodes[node]
    return 1 if left < 0 else 1 + max(_depth(nodes, int(left)), _depth(nodes, int(right)))


@pytest.mark.parametrize("name", list(MESHES))
def test_every_triangle_is_in_one_leaf_and_every_box_holds_its_triangles(name):
    vertices, triangles = MESHES[name]
    t = build_tables(vertices, triangles)
    assert sorted(map(tuple, t.triangles)) == sorted(map(tuple, triangles))        # the same triangles, reordered
    ranges = _ranges(t.nodes)
    assert len(ranges) == len(t.nodes) == len(t.boxes)                            # every node reached once
    assert ranges[0] == (0, len(triangles))
    corners = vertices[t.triangles]
    for node, (first, count) in ranges.items():
        left, right = t.nodes[node]
        if left < 0:
            assert 1 <= count <= LEAF
            listed = t.leaf_vertices[3 * first:3 * (first + count)]           # the leaf's distinct vertices, then -1
            distinct = listed[listed >= 0]
            assert np.all(listed[len(distinct):] == -1) and len(set(distinct)) == len(distinct)
            assert set(distinct) == set(t.triangles[first:first + count].ravel())
            assert np.array_equal(distinct[t.corner_slots[first:first + count]], t.triangles[first:first + count])
        else:
            assert count > LEAF
            assert min(ranges[int(left)][1], ranges[int(right)][1]) >= math.ceil(SHARE * count)
        centre, axes, half = t.boxes[node, :3], t.boxes[node, 3:12].reshape(3, 3), t.boxes[node, 12:]
        assert np.allclose(axes @ axes.T, np.eye(3), atol=1e-12)
        local = (corners[first:first + count].reshape(-1, 3) - centre) @ axes.T
        assert np.all(np.abs(local) <= half)
    assert t.depth == _depth(t.nodes)
    assert t.depth <= math.ceil(math.log(max(len(triangles) / LEAF, 1)) / math.log(4 / 3)) + 1


def test_the_depth_at_the_limit_is_below_the_query_s_stack():
    """The bound the query's fixed stack relies on (vfdsl/mesh/query.c: VFM_STACK 128, two entries a level)."""
    from vfdsl import limits
    assert math.ceil(math.log(limits.MESH_TRIANGLES / LEAF) / math.log(1 / (1 - SHARE))) + 1 < 128 // 2


def _probes(mesh, rng, n):
    """Points and capsules inside the channel (n each), and n points just outside it, straight out from an edge (the
    two triangles that share it give it at one distance; an end on the forbidden side keeps its nearest feature at
    any distance)."""
    vertices, triangles = mesh.vertices, mesh.triangles
    centre = np.array([0.004, 0.0, 0.27])
    a = centre + rng.uniform(-1, 1, (n, 3)) * [0.012, 0.008, 0.045]
    b = a + rng.normal(size=(n, 3)) * 0.015
    edge_normals = pseudo_normals(vertices, triangles)[1].reshape(-1, 3, 3)
    which, edge = rng.integers(len(triangles), size=n), rng.integers(3, size=n)
    p, q = vertices[triangles[which, edge]], vertices[triangles[which, (edge + 1) % 3]]
    out = p + rng.uniform(0.1, 0.9, (n, 1)) * (q - p) + edge_normals[which, edge] * rng.uniform(1e-4, 2e-3, (n, 1))
    return [*zip(a, a), *zip(a, b), *zip(out, out)]


def test_the_answer_does_not_depend_on_the_bvh(tmp_path, monkeypatch):
    """The channel's query built as usual, and from its triangles shuffled with other splits (each child at least
    45 % of its parent, leaves of 3): every output the same to the bit at 1,500 probes, keep in and keep out, with the
    example's cutoff and 10 um (where the nearest feature of an end outside is kept: ties between the two triangles
    of an edge, broken by the feature point's coordinates, not by the walk's order; the query before gave other bits
    in 7 of these 6,000 calls)."""
    mesh = read_mesh(CHANNEL, 1e-3)
    rng = np.random.default_rng(11)
    usual = mesh_query(mesh, K, tmp_path / "usual").function
    shuffled = dataclasses.replace(mesh, triangles=mesh.triangles[rng.permutation(len(mesh.triangles))])
    monkeypatch.setattr(tables, "SHARE", 0.45)
    monkeypatch.setattr(tables, "LEAF", 3)
    monkeypatch.setattr(external, "LEAF", 3)
    other = mesh_query(shuffled, K, tmp_path / "other").function
    for i, (a, b) in enumerate(_probes(mesh, rng, 500)):
        for cutoff in (0.0015 + REACH, 1e-5):
            for side in (-1.0, 1.0):
                first, second = ([np.array(x) for x in query(a, b, [cutoff, side])] for query in (usual, other))
                assert all(np.array_equal(x, y) for x, y in zip(first, second)), (i, cutoff, side)


def test_one_source_and_a_library_per_optimisation_level(tmp_path, monkeypatch):
    """$VFDSL_OPTIMIZE sets the query library's level as a task's (O0 in this suite): the library is named by its
    level beside the one source (written once), so a cache built at O0 never gives an O3 user its slower query, and
    the answers are the same to the bit (IEEE arithmetic at every level) at 200 probes."""
    mesh = read_mesh(CHANNEL, 1e-3)
    functions = {}
    for level in ("O0", "O3"):
        monkeypatch.setenv("VFDSL_OPTIMIZE", level)
        functions[level] = mesh_query(mesh, K, tmp_path).function
    [folder] = list(tmp_path.glob("meshes/vfmesh_*"))
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [f"{folder.name}.c", f"lib{folder.name}-O0.so", f"lib{folder.name}-O3.so"])
    for a, b in _probes(mesh, np.random.default_rng(5), 70):
        for side in (-1.0, 1.0):
            first, second = ([np.array(x) for x in f(a, b, [0.0015 + REACH, side])] for f in functions.values())
            assert all(np.array_equal(x, y) for x, y in zip(first, second))
