"""Distances to a mesh by brute force over all its triangles (NumPy): the reference for the C query, and what
``vfdsl check`` and ``vfdsl simulate`` measure clearance with.

Point to triangle: the closest point by Voronoi regions (Ericson 5.1.5), vectorized. Segment to triangle: 0 when
the segment crosses the triangle, else the least of its ends to the triangle and of it to the three edges
(the closest pair of a segment and a triangle that do not meet has a point on the triangle's boundary or an end
of the segment).
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


def _segments(p1, q1, p2, q2) -> np.ndarray:
    """Distances between the segment p1 q1 and segments p2[i] q2[i] (Ericson 5.1.9), vectorized."""
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
    x = p1 + s[:, None] * d1
    y = p2 + t[:, None] * d2
    return np.linalg.norm(x - y, axis=1)


def segment_distances(a: np.ndarray, b: np.ndarray, vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Distance from the segment a b (a point when a = b) to each triangle."""
    corners = vertices[triangles]
    a, b = np.asarray(a, float), np.asarray(b, float)
    best = np.linalg.norm(point_triangles(a, corners) - a, axis=1)
    if np.allclose(a, b):
        return best
    best = np.minimum(best, np.linalg.norm(point_triangles(b, corners) - b, axis=1))
    for e in range(3):
        best = np.minimum(best, _segments(a, b, corners[:, e], corners[:, (e + 1) % 3]))
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    da, db = np.einsum("ij,ij->i", a - corners[:, 0], normal), np.einsum("ij,ij->i", b - corners[:, 0], normal)
    crossing = np.flatnonzero(da * db < 0)
    if len(crossing):
        s = da[crossing] / (da[crossing] - db[crossing])
        x = a + s[:, None] * (b - a)
        c, n = corners[crossing], normal[crossing]
        inside = np.ones(len(crossing), dtype=bool)
        for e in range(3):     # x on the inner side of every edge, in the triangle's plane
            inside &= np.einsum("ij,ij->i", np.cross(c[:, (e + 1) % 3] - c[:, e], x - c[:, e]), n) >= 0
        best[crossing[inside]] = 0.0
    return best


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
