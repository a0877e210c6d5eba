"""Distances to a mesh by brute force over all its triangles (NumPy): the reference for the C query, and what
``vfdsl check`` and ``vfdsl simulate`` measure clearance with.

Point to triangle: the closest point by Voronoi regions (Ericson 5.1.5), vectorized. Segment to triangle: 0 when
the segment crosses the triangle, else the least of its ends to the triangle and of it to the three edges
(the closest pair of a segment and a triangle that do not meet has a point on the triangle's boundary or an end
of the segment). :func:`features` is the C query's answer (:mod:`vfdsl.mesh.external`, whose source states it)
computed from every triangle's hits.
"""

from __future__ import annotations

import numpy as np


def point_triangles(p: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Closest points (T x 3) of triangles ``corners`` (T x 3 x 3) to the point p."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 / (va + vb + vc)
        out = a + ab * (vb * denom)[:, None] + ac * (vc * denom)[:, None]
        cases = [
            (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
            (vb <= 0) & (d2 >= 0) & (d6 <= 0),
            (vc <= 0) & (d1 >= 0) & (d3 <= 0),
            (d6 >= 0) & (d5 <= d6),
            (d3 >= 0) & (d4 <= d3),
            (d1 <= 0) & (d2 <= 0),
        ]
        values = [
            b + ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None] * (c - b),
            a + (d2 / (d2 - d6))[:, None] * ac,
            a + (d1 / (d1 - d3))[:, None] * ab,
            c, b, a,
        ]
    for case, value in zip(cases, values):   # later cases take precedence, as in the sequential routine
        out = np.where(case[:, None], value, out)
    return out


def _segments(p1, q1, p2, q2) -> tuple[np.ndarray, np.ndarray]:
    """Closest points (T x 3 each) of the segment p1 q1 and segments p2[i] q2[i] (Ericson 5.1.9), vectorized."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = float(d1 @ d1), np.einsum("ij,ij->i", d2, d2)
    f, c, b = np.einsum("ij,ij->i", d2, r), r @ d1, d2 @ d1
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = a * e - b * b
        s = np.where(denom > 1e-30, np.clip((b * f - c * e) / denom, 0, 1), 0.0) if a > 1e-30 else np.zeros_like(e)
        t = (b * s + f) / e
        low, high = t < 0, t > 1
        t = np.clip(t, 0, 1)
        if a > 1e-30:
            s = np.where(low, np.clip(-c / a, 0, 1), np.where(high, np.clip((b - c) / a, 0, 1), s))
    return s, p2 + t[:, None] * d2


def _squared(x: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", x, x)


def segment_pairs(a: np.ndarray, b: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closest pair of the segment a b (not a point) and each triangle of ``corners``: the segment's parameter
    s, the triangle's point c and the distance (T each): the nearer end (a on a tie), replaced by the point where
    the segment crosses the face (distance 0), or else by a strictly nearer pair of the segment and an edge."""
    ca, cb = point_triangles(a, corners), point_triangles(b, corners)
    da2, db2 = _squared(a - ca), _squared(b - cb)
    far = db2 < da2
    best, s, c = np.where(far, db2, da2), far.astype(float), np.where(far[:, None], cb, ca)
    crossed = np.zeros(len(corners), dtype=bool)
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    da, db = np.einsum("ij,ij->i", a - corners[:, 0], normal), np.einsum("ij,ij->i", b - corners[:, 0], normal)
    crossing = np.flatnonzero(da * db < 0)
    if len(crossing):
        t = da[crossing] / (da[crossing] - db[crossing])
        x = a + t[:, None] * (b - a)
        inside = np.ones(len(crossing), dtype=bool)
        for e in range(3):     # x on the inner side of every edge, in the triangle's plane
            edge = corners[crossing, (e + 1) % 3] - corners[crossing, e]
            inside &= np.einsum("ij,ij->i", np.cross(edge, x - corners[crossing, e]), normal[crossing]) >= 0
        hit = crossing[inside]
        crossed[hit], best[hit], s[hit], c[hit] = True, 0.0, t[inside], x[inside]
    for e in range(3):
        t, y = _segments(a, b, corners[:, e], corners[:, (e + 1) % 3])
        d2 = _squared(a + t[:, None] * (b - a) - y)
        nearer = (d2 < best) & ~crossed
        best, s, c = np.where(nearer, d2, best), np.where(nearer, t, s), np.where(nearer[:, None], y, c)
    return s, c, np.sqrt(best)


def segment_distances(a: np.ndarray, b: np.ndarray, vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Distance from the segment a b (a point when a = b) to each triangle."""
    corners = vertices[triangles]
    a, b = np.asarray(a, float), np.asarray(b, float)
    if np.allclose(a, b):
        return np.linalg.norm(point_triangles(a, corners) - a, axis=1)
    return segment_pairs(a, b, corners)[2]


def features(a, b, vertices: np.ndarray, triangles: np.ndarray, cutoff: float, side: float, k: int,
             similar: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The C query's answer (d[k], s[k], u[3 x k]; see :mod:`vfdsl.mesh.external`) from every triangle's hits:
    its closest point to a (part 0) and to b (part 2), and its closest pair with the segment when that pair's
    point is strictly between a and b (part 1), within ``cutoff``; per part in the order (distance, part, c, s),
    a hit within ``similar`` (cosine) of one kept before it is merged; an end with no hit within the cutoff that
    lies on the forbidden side keeps its nearest feature, whatever its distance; the rows are the first kept hit of
    each part, then the nearest others. A part's side is read here from the winding number at its first hit's point
    (the query reads pseudo-normals: the same on a closed, consistently oriented mesh). The same answer up to
    rounding: where two hits' distances differ by rounding only (a shaft exactly parallel to a flat wall), which
    of them comes first may differ."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    corners = vertices[triangles]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    hits = []                                           # (dist, part, c0, c1, c2, s, x, u)
    ends = [(0, a)] if np.array_equal(a, b) else [(0, a), (2, b)]
    found = [(part, float(part == 2), point_triangles(x, corners), np.broadcast_to(x, corners.shape[:1] + (3,)))
             for part, x in ends]
    if len(ends) == 2:
        s, c, _ = segment_pairs(a, b, corners)
        inner = (s > 0) & (s < 1)
        found.append((1, s[inner], c[inner], a + s[inner, None] * (b - a), normal[inner]))
    for entry in found:
        part, s, c, x = entry[:4]
        faces = entry[4] if part == 1 else normal
        dist = np.sqrt(_squared(x - c))
        for i in np.flatnonzero(dist <= cutoff):
            u = (x[i] - c[i]) / dist[i] if dist[i] > 1e-12 else side * faces[i]
            hits.append((dist[i], part, *c[i], float(np.broadcast_to(s, dist.shape)[i]), x[i], u))
    hits.sort(key=lambda h: h[:6])
    kept: dict[int, list] = {0: [], 1: [], 2: []}
    for hit in hits:
        if all(float(other[7] @ hit[7]) <= similar for other in kept[hit[1]]):
            kept[hit[1]].append(hit)
    signs = {}
    for part, chosen in kept.items():
        if chosen:
            first = chosen[0]
            inside = first[0] > 0 and winding_number(first[6], vertices, triangles) > 0.5
            signs[part] = 1.0 if first[0] == 0 or inside == (side < 0) else -1.0
    for part, _, c, x in found[:len(ends)]:     # an end far on the forbidden side: its nearest feature, however far
        if not kept[part] and (winding_number(x[0], vertices, triangles) > 0.5) != (side < 0):
            dist = np.sqrt(_squared(x - c))
            i = int(np.argmin(dist))
            kept[part].append((dist[i], part, *c[i], float(part == 2), x[i], (x[i] - c[i]) / dist[i]))
            signs[part] = -1.0
    rows = [chosen[0] for chosen in kept.values() if chosen][:k]
    rows += sorted((h for chosen in kept.values() for h in chosen[1:]), key=lambda h: h[:6])[:k - len(rows)]
    rows.sort(key=lambda h: h[:6])
    d, s, u = np.full(k, np.inf), np.zeros(k), np.zeros((3, k))
    for i, hit in enumerate(rows):
        sign = signs[hit[1]] if hit[0] > 1e-12 else 1.0
        d[i], s[i], u[:, i] = sign * hit[0], hit[5], sign * hit[7]
    return d, s, u


def winding_number(p, vertices: np.ndarray, triangles: np.ndarray) -> float:
    """The generalized winding number of a closed mesh at p: 1 inside, 0 outside (for outward normals), the sum
    of the triangles' signed solid angles / 4 pi (Van Oosterom & Strackee's formula)."""
    r = vertices[triangles] - np.asarray(p, float)
    n = np.linalg.norm(r, axis=2)
    a, b, c = r[:, 0], r[:, 1], r[:, 2]
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = (n[:, 0] * n[:, 1] * n[:, 2] + np.einsum("ij,ij->i", a, b) * n[:, 2]
           + np.einsum("ij,ij->i", b, c) * n[:, 0] + np.einsum("ij,ij->i", c, a) * n[:, 1])
    return float(2 * np.arctan2(det, den).sum() / (4 * np.pi))


def signed_clearance(a, b, radius: float, vertices: np.ndarray, triangles: np.ndarray, keep_in: bool) -> float:
    """Clearance of the capsule (segment a b, ``radius``) from a closed mesh: its distance to the surface less the
    radius, negative through the surface; an end of the segment on the forbidden side (outside for ``keep_in``,
    inside otherwise) counts as a penetration by the distance plus the radius."""
    d = float(segment_distances(a, b, vertices, triangles).min())
    wrong = any((winding_number(x, vertices, triangles) > 0.5) != keep_in for x in (a, b))
    return -d - radius if wrong else d - radius
