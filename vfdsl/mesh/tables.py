"""The tables of the proximity query, built once per mesh with NumPy: a BVH and pseudo-normals.

**BVH.** Triangles are split recursively at the median of their centroids along the longest side of the
centroids' box, down to LEAF triangles. Nodes are numbered in depth-first order; an inner node stores its two
children, a leaf (-1 - first, count) for its triangles, which are renumbered so a leaf's triangles are
contiguous. Median splits bound the depth by ceil(log2(T / LEAF)) + 1 (18 for 1M triangles), far below the
query's fixed stack.

Each node keeps an oriented box holding its triangles: axes from the principal directions of its vertices
(or the world's axes when their box is smaller), centre and half-sides from the vertices' extents along them,
widened by PAD so that the query's rounding cannot put a triangle outside. Anatomy is curved and seldom
axis-aligned: a leaf of a wall is a thin oriented box, and the query's distance bounds (the exact point-box
distance and a lower bound of the segment-box distance, in the box's frame) stay close to the triangles' own
distances.

**Pseudo-normals** (Baerentzen & Aanaes, IEEE TVCG 2005) give the side of a point x relative to its closest
feature c of a closed, consistently oriented mesh: sign((x - c) . n_c) with n_c the face normal (face), the
sum of the two faces' normals (edge), or the angle-weighted sum of the incident faces' normals (vertex). On an
open mesh they still say on which side of the nearby surface x lies, by the file's orientation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LEAF = 8
PAD = 1e-12
"""m: the oriented boxes' half-sides are widened by this (a picometre: rounding in the query is far below)."""


@dataclass(frozen=True, eq=False)
class Tables:
    vertices: np.ndarray          # V x 3
    triangles: np.ndarray         # T x 3, in BVH order
    face_normals: np.ndarray      # T x 3, unit
    edge_normals: np.ndarray      # T x 9: per triangle edge (0,1), (1,2), (2,0), unit
    vertex_normals: np.ndarray    # V x 3, unit
    nodes: np.ndarray             # N x 2 int: children, or (-1 - first, count)
    boxes: np.ndarray             # N x 15: centre, axes (3 rows of a rotation), half-sides
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


def oriented_boxes(points: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Boxes (n x 15: centre, axes as 3 rows, half-sides) around groups of ``points``, group i from row starts[i]
    to the next start: per group the box along its points' principal axes or along the world's, the smaller."""
    counts = np.diff(np.append(starts, len(points)))
    mean = np.add.reduceat(points, starts) / counts[:, None]
    centred = points - np.repeat(mean, counts, axis=0)
    cov = np.add.reduceat(centred[:, :, None] * centred[:, None, :], starts)
    principal = np.linalg.eigh(cov)[1].transpose(0, 2, 1)[:, ::-1]          # rows, largest first
    best = None
    for axes in (np.broadcast_to(np.eye(3), principal.shape), principal):
        local = np.einsum("nij,nj->ni", np.repeat(axes, counts, axis=0), centred)
        lo, hi = np.minimum.reduceat(local, starts), np.maximum.reduceat(local, starts)
        half = 0.5 * (hi - lo)
        centre = mean + np.einsum("ni,nij->nj", 0.5 * (lo + hi), axes)
        box = np.concatenate([centre, axes.reshape(-1, 9), half + PAD], axis=1)
        if best is None:
            best = box
        else:
            smaller = np.prod(half + PAD, axis=1) < np.prod(best[:, 12:] , axis=1)
            best[smaller] = box[smaller]
    return best


def build_tables(vertices: np.ndarray, triangles: np.ndarray) -> Tables:
    corners = vertices[triangles]
    centroids = corners.mean(axis=1)
    order = np.arange(len(triangles))
    nodes: list[list[int]] = [[0, 0]]
    spans: list[tuple[int, int]] = [(0, len(order))]
    levels: list[int] = [1]
    # (node index, first, end, depth): children are written when their parent is split
    pending = [(0, 0, len(order), 1)]
    while pending:
        node, first, end, level = pending.pop()
        span = order[first:end]
        if end - first <= LEAF:
            nodes[node] = [-1 - first, end - first]
            continue
        c = centroids[span]
        axis = int(np.argmax(np.ptp(c, axis=0)))
        half = (end - first) // 2
        order[first:end] = span[np.argpartition(c[:, axis], half)]
        left, right = len(nodes), len(nodes) + 1
        nodes += [[0, 0], [0, 0]]
        spans += [(first, first + half), (first + half, end)]
        levels += [level + 1, level + 1]
        nodes[node] = [left, right]
        pending += [(right, first + half, end, level + 1), (left, first, first + half, level + 1)]
    ordered = triangles[order]
    points = vertices[ordered].reshape(-1, 3)              # a node's corners: rows 3 first ... 3 end
    boxes = np.empty((len(nodes), 15))
    spans_array, levels_array = np.array(spans), np.array(levels)
    for level in np.unique(levels_array):                 # the nodes of one level hold disjoint triangles
        which = np.flatnonzero(levels_array == level)
        first, end = 3 * spans_array[which, 0], 3 * spans_array[which, 1]
        counts = end - first
        rows = np.repeat(first - np.cumsum(np.append(0, counts[:-1])), counts) + np.arange(counts.sum())
        boxes[which] = oriented_boxes(points[rows], np.cumsum(np.append(0, counts[:-1])))
    faces, edge_normals, vertex_normals = pseudo_normals(vertices, ordered)
    return Tables(vertices, ordered, faces, edge_normals, vertex_normals, np.array(nodes, dtype=np.int64),
                  boxes, int(levels_array.max()))
