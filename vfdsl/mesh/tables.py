"""The tables of the proximity query, built once per mesh with NumPy: a BVH and pseudo-normals.

**BVH.** Triangles are split recursively at the median of their centroids along the longest side of the
centroids' box, down to LEAF triangles; each node keeps the box of its triangles (min, max corners). Nodes are
numbered in depth-first order; an inner node stores its two children, a leaf (-1 - first, count) for its
triangles, which are renumbered so a leaf's triangles are contiguous. Median splits bound the depth by
ceil(log2(T / LEAF)) + 1 (18 for 1M triangles), far below the query's fixed stack.

**Pseudo-normals** (Baerentzen & Aanaes, IEEE TVCG 2005) give the side of a point x relative to its closest
feature c of a closed, consistently oriented mesh: sign((x - c) . n_c) with n_c the face normal (face), the
sum of the two faces' normals (edge), or the angle-weighted sum of the incident faces' normals (vertex). On an
open mesh they still say on which side of the nearby surface x lies, by the file's orientation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LEAF = 4


@dataclass(frozen=True, eq=False)
class Tables:
    vertices: np.ndarray          # V x 3
    triangles: np.ndarray         # T x 3, in BVH order
    face_normals: np.ndarray      # T x 3, unit
    edge_normals: np.ndarray      # T x 9: per triangle edge (0,1), (1,2), (2,0), unit
    vertex_normals: np.ndarray    # V x 3, unit
    nodes: np.ndarray             # N x 2 int: children, or (-1 - first, count)
    boxes: np.ndarray             # N x 6: min corner, max corner
    depth: int


def _unit(x: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(x, axis=-1, keepdims=True)
    return np.divide(x, norm, out=np.zeros_like(x), where=norm > 0)


def pseudo_normals(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(face, edge (T x 9), vertex) unit pseudo-normals."""
    corners = vertices[triangles]                                   # T x 3 x 3
    faces = _unit(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    edges = np.stack([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]], axis=1)  # T x 3 x 2
    keys = np.sort(edges, axis=2).reshape(-1, 2)
    _, which = np.unique(keys, axis=0, return_inverse=True)
    which = which.reshape(-1)
    summed = np.zeros((which.max() + 1, 3))
    np.add.at(summed, which, np.repeat(faces, 3, axis=0))
    edge_normals = _unit(summed[which]).reshape(-1, 9)
    angles = np.empty((len(triangles), 3))
    for i in range(3):
        u = _unit(corners[:, (i + 1) % 3] - corners[:, i])
        v = _unit(corners[:, (i + 2) % 3] - corners[:, i])
        angles[:, i] = np.arccos(np.clip(np.sum(u * v, axis=1), -1.0, 1.0))
    vertex_normals = np.zeros_like(vertices)
    for i in range(3):
        np.add.at(vertex_normals, triangles[:, i], angles[:, i, None] * faces)
    return faces, edge_normals, _unit(vertex_normals)


def build_tables(vertices: np.ndarray, triangles: np.ndarray) -> Tables:
    corners = vertices[triangles]
    centroids = corners.mean(axis=1)
    lows, highs = corners.min(axis=1), corners.max(axis=1)
    order = np.arange(len(triangles))
    nodes: list[list[int]] = []
    boxes: list[np.ndarray] = []
    depth = 0
    # (node index, first, end, depth): children are written when their parent is split
    pending = [(0, 0, len(order), 1)]
    nodes.append([0, 0])
    boxes.append(np.zeros(6))
    while pending:
        node, first, end, level = pending.pop()
        depth = max(depth, level)
        span = order[first:end]
        boxes[node] = np.concatenate([lows[span].min(axis=0), highs[span].max(axis=0)])
        if end - first <= LEAF:
            nodes[node] = [-1 - first, end - first]
            continue
        c = centroids[span]
        axis = int(np.argmax(np.ptp(c, axis=0)))
        half = (end - first) // 2
        order[first:end] = span[np.argpartition(c[:, axis], half)]
        left, right = len(nodes), len(nodes) + 1
        nodes += [[0, 0], [0, 0]]
        boxes += [np.zeros(6), np.zeros(6)]
        nodes[node] = [left, right]
        pending += [(right, first + half, end, level + 1), (left, first, first + half, level + 1)]
    ordered = triangles[order]
    faces, edge_normals, vertex_normals = pseudo_normals(vertices, ordered)
    return Tables(vertices, ordered, faces, edge_normals, vertex_normals, np.array(nodes, dtype=np.int64),
                  np.array(boxes), depth)
