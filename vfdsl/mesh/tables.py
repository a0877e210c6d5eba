"""The tables of the proximity query, built once per mesh with NumPy: a BVH, each leaf's distinct vertices
(:func:`leaf_corners`) and pseudo-normals.

**BVH.** Triangles are split recursively, one level at a time, down to LEAF triangles: a node's triangles are
ordered by their centroids along nine directions (the world's axes, the principal axes of the centroids and of the
corners), each cut where the two children's spread is least (a surface-area heuristic on the corners' covariance),
each child keeping at least SHARE of them, and the cut whose two boxes have the least volume is taken
(:func:`_splits`). Nodes are numbered level by level, the two children of a node side by side; an inner node stores
its two children, a leaf (-1 - first, count) for its triangles, which are renumbered so a leaf's triangles are
contiguous. A child holds at most 3/4 of its parent's triangles, so the depth is at most
ceil(log(T / LEAF) / log(4 / 3)) + 1 (34 for the 100,000 triangles of limits.MESH_TRIANGLES), below the query's
fixed stack (VFM_STACK / 2 = 64).

The split matters along a wall, where the query works longest: the median of the centroids along the longest side of
their box (this module's rule before) cut a curved wall into boxes that the shaft's neighbourhood touched in more
places. On tasks/sinus_channel.vf's channel at 10k triangles, with the shaft pushed into the bend's wall
(benchmarks/mesh.py's slowest states), the query expands 400 triangles in 61 leaves where it expanded 507 in 103 (391
lie within the distance at which the walk stops), and runs 0.64 of the instructions (0.60 over all the run's
states). The answer does not depend on the BVH (the order of hits is total, the nearest feature's ties are broken by
coordinates): bit for bit the same with either rule.

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
SHARE = 0.25
"""Each child of a split holds at least this share of its parent's triangles (the depth's bound)."""
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
    leaf_vertices: np.ndarray     # 3T: a leaf's distinct vertices from 3 first on (first as in nodes), then -1
    corner_slots: np.ndarray      # T x 3: each corner's place among its leaf's distinct vertices


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


def _scatter(points: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per group of ``points`` (group i from row starts[i] to the next start): its count, its mean, the points less
    their group's mean, and the group's scatter matrix (the sum of their outer products: the covariance times the
    count, with the same principal axes)."""
    counts = np.diff(np.append(starts, len(points)))
    mean = np.add.reduceat(points, starts) / counts[:, None]
    centred = points - np.repeat(mean, counts, axis=0)
    x, y, z = centred.T
    sums = np.add.reduceat(np.column_stack([x * x, y * y, z * z, x * y, x * z, y * z]), starts)
    return counts, mean, centred, sums[:, [[0, 3, 4], [3, 1, 5], [4, 5, 2]]]


def oriented_boxes(points: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Boxes (n x 15: centre, axes as 3 rows, half-sides) around groups of ``points``, group i from row starts[i]
    to the next start: per group the box along its points' principal axes or along the world's, the smaller."""
    counts, mean, centred, scatter = _scatter(points, starts)
    principal = np.linalg.eigh(scatter)[1].transpose(0, 2, 1)[:, ::-1]          # rows, largest first
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


def _spread(moments: np.ndarray, n: np.ndarray) -> np.ndarray:
    """s1 s2 + s2 s3 + s1 s3 for the standard deviations s_i of n points along their principal axes, from the points'
    sums and their products' sums (moments: x, y, z, xx, yy, zz, xy, xz, yz), by the closed form of a symmetric 3 x 3
    matrix's eigenvalues (trigonometric): the sides' areas of a box that fits the points' spread, a split's cost."""
    m = moments / n[:, None]
    xx, yy, zz = m[:, 3] - m[:, 0] ** 2, m[:, 4] - m[:, 1] ** 2, m[:, 5] - m[:, 2] ** 2
    xy, xz, yz = m[:, 6] - m[:, 0] * m[:, 1], m[:, 7] - m[:, 0] * m[:, 2], m[:, 8] - m[:, 1] * m[:, 2]
    q = (xx + yy + zz) / 3
    a, b, c = xx - q, yy - q, zz - q
    p = np.sqrt((a * a + b * b + c * c + 2 * (xy * xy + xz * xz + yz * yz)) / 6)
    det = a * (b * c - yz * yz) - xy * (xy * c - yz * xz) + xz * (xy * yz - b * xz)
    safe = np.where(p > 0, p, 1.0)
    phi = np.arccos(np.clip(det / (2 * safe ** 3), -1.0, 1.0)) / 3
    high, low = q + 2 * p * np.cos(phi), q + 2 * p * np.cos(phi + 2 * np.pi / 3)
    s1, s2, s3 = (np.sqrt(np.clip(x, 0, None)) for x in (high, 3 * q - high - low, low))
    return s1 * s2 + s2 * s3 + s1 * s3


def _starts(count: np.ndarray) -> np.ndarray:
    """Where each of runs of these lengths starts when they follow one another."""
    return np.append(0, np.cumsum(count)[:-1])


def _runs(first: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The indices first_j ... first_j + count_j - 1 of every j, one run after another, and where each run starts."""
    start = _starts(count)
    return np.repeat(first - start, count) + np.arange(count.sum()), start


def _splits(corner: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The splits of one level's nodes, node j the next count_j triangles of ``corner`` (n x 3 x 3): the permutation
    of the rows that puts each node's left child first, each left child's count, and the children's boxes (2 nodes x
    15, each node's left then right: :func:`oriented_boxes` of their corners in that order).

    A node's triangles are ordered by their centroids along each of nine directions (the world's axes, the principal
    axes of the centroids, of the corners); along each, of the cuts that leave each child at least SHARE of them, the
    one whose children's spread (:func:`_spread` of their corners) is least (prefix sums give every cut's covariances
    at once); of these nine, the one whose children's boxes (:func:`oriented_boxes`) have the least volume in all."""
    nodes = len(count)
    node, start = np.repeat(np.arange(nodes), count), _starts(count)
    centroid = corner.mean(axis=1)
    _, mean, _, centroid_scatter = _scatter(centroid, start)
    corner_scatter = _scatter(corner.reshape(-1, 3), 3 * start)[3]
    directions = np.concatenate([np.broadcast_to(np.eye(3), (nodes, 3, 3)),
                                 np.linalg.eigh(centroid_scatter)[1].transpose(0, 2, 1),
                                 np.linalg.eigh(corner_scatter)[1].transpose(0, 2, 1)], axis=1)   # nodes x 9 x 3
    centred = corner - mean[node][:, None, :]
    x, y, z = centred[:, :, 0], centred[:, :, 1], centred[:, :, 2]
    moments = np.stack([w.sum(axis=1) for w in (x, y, z, x * x, y * y, z * z, x * y, x * z, y * z)], axis=1)
    low = np.minimum(np.ceil(SHARE * count).astype(int), count // 2)
    cuts = count - 2 * low + 1                                       # a node's cuts: left counts low ... count - low
    cut_node = np.repeat(np.arange(nodes), cuts)
    left, cut_start = _runs(low, cuts)
    best_volume, best_left, best_order = np.full(nodes, np.inf), np.zeros(nodes, dtype=int), np.arange(len(node))
    best_boxes = np.empty((2 * nodes, 15))
    for k in range(directions.shape[1]):
        order = np.lexsort((np.einsum("ni,ni->n", centroid, directions[node, k]), node))
        prefix = np.concatenate([np.zeros((1, 9)), np.cumsum(moments[order], axis=0)])   # sums of the rows before
        before = prefix[start]
        inner = prefix[start[cut_node] + left] - before[cut_node]
        outer = prefix[start + count][cut_node] - before[cut_node] - inner
        spread = _spread(inner, 3.0 * left) + _spread(outer, 3.0 * (count[cut_node] - left))
        cut = left[np.lexsort((spread, cut_node))[cut_start]]          # each node's least spread, its first cut
        boxes = oriented_boxes(corner[order].reshape(-1, 3), 3 * np.column_stack([start, start + cut]).ravel())
        volume = np.prod(boxes[:, 12:], axis=1).reshape(-1, 2).sum(axis=1)
        better = (volume < best_volume) | (k == 0)                     # the first direction's cut whatever its volume
        best_volume[better], best_left[better] = volume[better], cut[better]
        best_boxes.reshape(nodes, 2, 15)[better] = boxes.reshape(nodes, 2, 15)[better]
        take = better[node]
        best_order[take] = order[take]
    return best_order, best_left, best_boxes


def leaf_corners(triangles: np.ndarray, nodes: np.ndarray, vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Each leaf's distinct vertices, written from 3 first on (its triangles first ... first + count - 1) and -1 after
    them, and each corner's place among them: the query projects a leaf's vertices once, not once per corner (a leaf of
    8 triangles of a wall has ~10 distinct vertices for its 24 corners)."""
    leaf = nodes[:, 0] < 0
    first, count = -1 - nodes[leaf, 0], nodes[leaf, 1]
    owner = np.empty(len(triangles), dtype=np.int64)
    owner[_runs(first, count)[0]] = np.repeat(np.arange(len(first)), count)
    keys = np.repeat(owner, 3) * vertices + triangles.reshape(-1)
    distinct, slot = np.unique(keys, return_inverse=True)
    distinct_owner = distinct // vertices
    start = np.searchsorted(distinct_owner, np.arange(len(first)))
    slots = slot.reshape(-1) - start[np.repeat(owner, 3)]
    out = np.full(3 * len(triangles), -1, dtype=np.int64)
    out[3 * first[distinct_owner] + np.arange(len(distinct)) - start[distinct_owner]] = distinct % vertices
    return out, slots.reshape(-1, 3)


def build_tables(vertices: np.ndarray, triangles: np.ndarray) -> Tables:
    order = np.arange(len(triangles))
    nodes = np.zeros((max(2 * len(triangles) - 1, 1), 2), dtype=np.int64)
    boxes = np.empty((len(nodes), 15))
    ids, first, count = np.array([0]), np.array([0]), np.array([len(triangles)])
    boxes[0] = oriented_boxes(vertices[triangles].reshape(-1, 3), np.array([0]))[0]
    size, depth = 1, 0
    while len(ids):                                       # one level at a time, its nodes' triangles disjoint
        depth += 1
        leaf = count <= LEAF
        nodes[ids[leaf]] = np.column_stack([-1 - first[leaf], count[leaf]])
        ids, first, count = ids[~leaf], first[~leaf], count[~leaf]
        if not len(ids):
            break
        rows = _runs(first, count)[0]
        split, left, child_boxes = _splits(vertices[triangles[order[rows]]], count)
        order[rows] = order[rows[split]]
        children = size + 2 * np.arange(len(ids))
        nodes[ids] = np.column_stack([children, children + 1])
        size += 2 * len(ids)
        ids = np.column_stack([children, children + 1]).ravel()
        boxes[ids] = child_boxes
        first, count = np.column_stack([first, first + left]).ravel(), np.column_stack([left, count - left]).ravel()
    ordered = triangles[order]
    faces, edge_normals, vertex_normals = pseudo_normals(vertices, ordered)
    leaf_vertices, corner_slots = leaf_corners(ordered, nodes[:size], len(vertices))
    return Tables(vertices, ordered, faces, edge_normals, vertex_normals, nodes[:size], boxes[:size], depth,
                  leaf_vertices, corner_slots)
