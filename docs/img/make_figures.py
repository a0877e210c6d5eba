"""Figures for docs/primitives.md, and the polytope numbers quoted there.

    python docs/img/make_figures.py            # writes the PNGs next to this file, prints the tables

Everything here is computed from the seed's formulas with numpy/scipy (no vfdsl import), so the figures show
the math the compiler is tested against:

- sphere polytope, Li, Kapoor & Taylor eq. (3), repeated directions removed; its vertices by brute-force
  enumeration (every triple of facet planes, kept if it satisfies all facets) -> worst-case vertex distance;
- polygon, eqs. (8)-(9): faces at eps, vertices at eps / cos(pi / n);
- cone, eqs. (22)-(23); follow a curve (experiment A) with closest points by dense brute force.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import yaml
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from scipy.interpolate import make_interp_spline
from scipy.spatial import ConvexHull

from vfdsl.compiler.geometry import (
    sphere_directions,  # the figures show what vfdsl builds
)

plt.switch_backend("Agg")

OUT = Path(__file__).resolve().parent
DPI = 110


# ============================================================================================ polytopes

def polytope_vertices(U: np.ndarray) -> np.ndarray:
    """Vertices of {x : U x <= 1} by brute force: every triple of facet planes, kept if feasible."""
    found: list[np.ndarray] = []
    for i, j, k in itertools.combinations(range(len(U)), 3):
        M = U[[i, j, k]]
        if abs(np.linalg.det(M)) < 1e-12:
            continue
        x = np.linalg.solve(M, np.ones(3))
        if np.all(U @ x <= 1 + 1e-9) and all(np.linalg.norm(x - v) > 1e-9 for v in found):
            found.append(x)
    return np.array(found)


def is_bounded(U: np.ndarray) -> bool:
    """{x : U x <= 1} is bounded iff the origin is strictly inside the convex hull of the directions."""
    try:
        return bool(np.all(ConvexHull(U).equations[:, 3] < -1e-12))
    except Exception:  # noqa: BLE001  (qhull refuses a flat set of directions: unbounded)
        return False


SPHERE_RESOLUTIONS = [(3, 3), (4, 4), (5, 5), (6, 6), (8, 8), (10, 10), (12, 12), (4, 8), (8, 4)]
POLYGON_SIDES = [3, 4, 6, 8, 12, 16]


def sphere_table() -> list[tuple[tuple[int, int], int, int, float]]:
    rows = []
    for n, m in SPHERE_RESOLUTIONS:
        U = sphere_directions(n, m)
        assert is_bounded(U)
        V = polytope_vertices(U)
        rows.append(((n, m), n * m, len(U), float(np.linalg.norm(V, axis=1).max()), len(V)))
    return rows


# ============================================================================================== figures

def _sphere_wire(ax, r=1.0, color="0.6"):
    u, v = np.mgrid[0:2 * np.pi:40j, 0:np.pi:20j]
    ax.plot_wireframe(r * np.cos(u) * np.sin(v), r * np.sin(u) * np.sin(v), r * np.cos(v), color=color,
                      linewidth=0.3)


def _polytope_faces(U: np.ndarray, V: np.ndarray) -> list[np.ndarray]:
    faces = []
    for u in U:
        on = V[np.abs(V @ u - 1) < 1e-9]
        if len(on) < 3:
            continue
        c = on.mean(axis=0)
        e1 = on[0] - c
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        order = np.argsort(np.arctan2((on - c) @ e2, (on - c) @ e1))
        faces.append(on[order])
    return faces


def figure_sphere_polytopes():
    fig = plt.figure(figsize=(12, 4.3))
    for k, (n, m) in enumerate([(4, 4), (6, 6), (8, 8)]):
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        U = sphere_directions(n, m)
        V = polytope_vertices(U)
        r = np.linalg.norm(V, axis=1)
        ax.add_collection3d(Poly3DCollection(_polytope_faces(U, V), facecolor="tab:blue", alpha=0.25,
                                             edgecolor="tab:blue", linewidth=0.8))
        _sphere_wire(ax)
        far = V[np.argmax(r)]
        ax.plot([0, far[0]], [0, far[1]], [0, far[2]], color="tab:red", linewidth=2)
        ax.scatter(*far, color="tab:red", s=15)
        ax.set_title(f"{n} x {m}: {len(U)} unique facets\nfarthest vertex {r.max():.3f} eps", fontsize=10)
        lim = 1.25
        ax.set_xlim(-lim, lim), ax.set_ylim(-lim, lim), ax.set_zlim(-lim, lim)
        ax.set_box_aspect((1, 1, 1))
        ax.set_xticks([-1, 0, 1]), ax.set_yticks([-1, 0, 1]), ax.set_zticks([-1, 0, 1])
        ax.view_init(elev=20, azim=35)
    fig.suptitle("Sphere polytope of eq. (3), duplicates removed: faces at eps (unit sphere), vertices beyond it",
                 fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.92))
    fig.savefig(OUT / "sphere_polytopes.png", dpi=DPI)
    plt.close(fig)


def figure_polygon_line():
    fig = plt.figure(figsize=(11, 4.6))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    l = np.array([1.0, 1.0, 0.4])
    l /= np.linalg.norm(l)
    helper = np.array([1.0, 0, 0]) if abs(l[0]) < 0.9 else np.array([0, 1.0, 0])
    v1 = np.cross(l, helper)
    v1 /= np.linalg.norm(v1)
    v2 = np.cross(v1, l)
    n, eps = 8, 1.0
    R = eps / math.cos(math.pi / n)
    corners = [R * (math.cos(a) * v1 + math.sin(a) * v2)
               for a in 2 * np.pi * (np.arange(1, n + 1) + 0.5) / n]
    s = np.linspace(-4, 4, 2)
    ax.plot(*(np.outer(s, l)).T, color="k", linewidth=2, label="line L(s) = L0 + l s")
    for t in np.linspace(-4, 4, 5):
        ring = np.array(corners + [corners[0]]) + t * l
        ax.plot(*ring.T, color="tab:blue", linewidth=0.8)
    for c in corners:
        ax.plot(*np.array([c - 4 * l, c + 4 * l]).T, color="tab:blue", linewidth=0.4)
    x = 0.5 * v1 - 0.6 * v2 + 1.5 * l
    ax.scatter(*x, color="tab:red")
    ax.text(*(x + [0, 0, 0.4]), "p", color="tab:red")
    P_cl = (x @ l) * l
    ax.plot(*np.array([P_cl, x]).T, color="tab:red", linestyle="--")
    ax.text(*(P_cl - [0, 0, 0.7]), "P_cl", fontsize=8)
    ax.set_title("along(line): an octagonal prism around the line", fontsize=10)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlim(-3, 3), ax.set_ylim(-3, 3), ax.set_zlim(-3, 3)
    ax.legend(loc="upper left", fontsize=8)

    ax = fig.add_subplot(1, 2, 2)
    t = np.linspace(0, 2 * np.pi, 300)
    ax.plot(np.cos(t), np.sin(t), color="0.5", label="circle of radius eps (eq. 7)")
    for n, style in [(4, ":"), (6, "-."), (8, "-")]:
        a = 2 * np.pi * np.arange(1, n + 1) / n
        R = 1 / math.cos(math.pi / n)
        va = a + np.pi / n
        P = np.column_stack([R * np.cos(va), R * np.sin(va)])
        P = np.vstack([P, P[:1]])
        ax.plot(*P.T, style, label=f"{n}-gon: vertices at {R:.3f} eps")
        if n == 8:
            for ai in a:
                ax.annotate("", xy=(np.cos(ai), np.sin(ai)), xytext=(0, 0),
                            arrowprops={"arrowstyle": "->", "color": "tab:green", "lw": 0.8})
    ax.text(0.05, -0.15, "u_i = R3 [cos a_i, sin a_i, 0]", color="tab:green", fontsize=8)
    ax.set_aspect("equal")
    ax.set_title("cross-section normal to l (eq. 9): faces at eps, corners at eps / cos(pi/n)", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_xlim(-1.6, 1.6), ax.set_ylim(-1.6, 1.6)
    fig.tight_layout()
    fig.savefig(OUT / "polygon_line.png", dpi=DPI)
    plt.close(fig)


def figure_cone():
    """Eqs. (22)-(23) with l_a vertical, gamma = 15 deg... drawn at 30 deg for legibility."""
    gamma, theta = math.radians(30), math.radians(45)
    l_a = np.array([0, 0, 1.0])
    e = np.array([1.0, 0, 0])
    l_t = math.cos(theta) * l_a + math.sin(theta) * e                  # the tool, off the cone
    c = np.cross(l_t, l_a)
    d1 = c / np.linalg.norm(c)
    d2 = np.cross(d1, l_a)
    d2 /= np.linalg.norm(d2)
    R = np.column_stack([d2, l_a, -d1])
    w_d = R @ np.array([math.cos(gamma), math.sin(gamma), 0])        # eq. (22)
    delta_r = d1 * math.sin(gamma) - c                                 # eq. (23)
    l_star = math.cos(gamma) * l_a + math.sin(gamma) * e               # nearest tool direction on the cone
    fig = plt.figure(figsize=(7.5, 6.5))
    ax = fig.add_subplot(projection="3d")
    phi, h = np.meshgrid(np.linspace(0, 2 * np.pi, 40), np.linspace(0, 1.2, 8))
    ax.plot_surface(h * math.tan(gamma) * np.cos(phi), h * math.tan(gamma) * np.sin(phi), h, alpha=0.15,
                    color="tab:orange", linewidth=0)

    def arrow(v, color, label, scale=1.2):
        ax.quiver(0, 0, 0, *(scale * v), color=color, arrow_length_ratio=0.08, linewidth=2)
        ax.text(*(scale * 1.08 * v), label, color=color, fontsize=10)

    arrow(l_a, "k", "l_a (cone axis)")
    arrow(l_t, "tab:red", "l_t (tool)")
    arrow(l_star, "tab:orange", "l* (on the cone)")
    arrow(d1, "tab:purple", "d1 = l_t x l_a / |.|", 0.8)
    arrow(d2, "tab:brown", "d2 = d1 x l_a / |.|", 0.8)
    arrow(w_d, "tab:blue", "w_d = R [cos g, sin g, 0]")
    # the plane normal to w_d: spanned by d1 and l*, the tool's allowed plane this tick
    s, t = np.meshgrid(np.linspace(-0.8, 0.8, 2), np.linspace(0, 1.2, 2))
    P = s[..., None] * d1 + t[..., None] * l_star
    ax.plot_surface(P[..., 0], P[..., 1], P[..., 2], alpha=0.2, color="tab:blue")
    ax.text(*(0.7 * d1 + 1.1 * l_star), "plane normal to w_d\n(contains l* and d1)", color="tab:blue", fontsize=8)
    ax.set_title(f"cone(axis, gamma), eqs. (22)-(23): gamma = {math.degrees(gamma):.0f} deg, "
                 f"tool at {math.degrees(theta):.0f} deg\n"
                 f"delta_r = d1 sin g - l_t x l_a = (sin g - sin theta) d1 = {delta_r @ d1:+.3f} d1", fontsize=10)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlim(-0.9, 0.9), ax.set_ylim(-0.9, 0.9), ax.set_zlim(-0.2, 1.4)
    ax.view_init(elev=18, azim=-60)
    fig.tight_layout()
    fig.savefig(OUT / "cone_geometry.png", dpi=DPI)
    plt.close(fig)


SCENE_A = Path(__file__).resolve().parents[2] / "tasks" / "paper_a_follow_curve.yaml"
PAPER_A = np.array(yaml.safe_load(SCENE_A.read_text())["params"]["path"]["points"], dtype=float)  # mm, plate


def figure_follow_curve():
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(PAPER_A, axis=0), axis=1))])
    rng = np.random.default_rng(5)
    for ax, degree in zip(axes, (5, 3)):
        spline = make_interp_spline(s, PAPER_A, k=degree)
        grid = np.linspace(0, s[-1], 20001)
        C = spline(grid)
        ax.plot(C[:, 0], C[:, 1], color="k", linewidth=1.2, label=f"degree-{degree} b-spline (chord length)")
        ax.plot(PAPER_A[:, 0], PAPER_A[:, 1], "o", color="tab:blue", label="digitized points (scene)")
        knots = np.unique(spline.t)
        K = spline(knots)
        ax.plot(K[:, 0], K[:, 1], "s", color="tab:green", ms=5, label="knots (span ends)")
        for _ in range(14):
            x = spline(rng.uniform(0, s[-1])) + rng.normal(scale=3.0, size=3) * [1, 1, 0]
            i = np.argmin(np.sum((C - x) ** 2, axis=1))
            ax.plot([x[0], C[i, 0]], [x[1], C[i, 1]], color="tab:red", linewidth=0.8)
            ax.plot(*x[:2], ".", color="tab:red")
            tangent = spline.derivative()(grid[i])
            tangent /= np.linalg.norm(tangent)
            ax.arrow(C[i, 0], C[i, 1], 4 * tangent[0], 4 * tangent[1], color="tab:orange", width=0.15)
        ax.set_aspect("equal")
        ax.set_xlabel("plate x [mm]"), ax.set_ylabel("plate y [mm]")
        ax.set_title(f"follows(path): tip (red dot) -> closest point, tangent (orange); degree {degree}",
                     fontsize=10)
    axes[0].legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(OUT / "follow_curve.png", dpi=DPI)
    plt.close(fig)


def figure_plane_port():
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.3))
    ax = axes[0]
    ax.axhline(0, color="k")
    ax.fill_between([-3, 3], -1.5, 0, color="0.85")
    ax.fill_between([-3, 3], 0, 0.35, color="tab:green", alpha=0.25)
    ax.text(-2.9, -0.8, "forbidden side", fontsize=9)
    ax.text(-2.9, 0.1, "on_plane band: 0 <= d.(delta + dx) <= eps", fontsize=8, color="tab:green")
    ax.annotate("", xy=(-1.5, 1), xytext=(-1.5, 0), arrowprops={"arrowstyle": "->", "lw": 1.5})
    ax.text(-1.45, 0.8, "d (free side)")
    p = np.array([1.2, 1.1])
    ax.plot(*p, "o", color="tab:red")
    ax.text(p[0] + 0.05, p[1] + 0.05, "p", color="tab:red")
    ax.plot([p[0], p[0]], [0, p[1]], "--", color="tab:red")
    ax.text(p[0] + 0.05, 0.5, "delta = p - P_cl", color="tab:red", fontsize=9)
    ax.plot(p[0], 0, "s", color="k")
    ax.text(p[0] + 0.05, -0.25, "P_cl")
    ax.annotate("", xy=(p[0] - 0.6, p[1] - 1.4), xytext=p, arrowprops={"arrowstyle": "->", "color": "tab:blue"})
    ax.text(p[0] - 0.9, -0.5, "dx_p: cut so that\nd.(delta + dx_p) >= 0", color="tab:blue", fontsize=8)
    ax.set_xlim(-3, 3), ax.set_ylim(-1.5, 2)
    ax.set_aspect("equal")
    ax.set_title("above(plane) and on_plane(plane), eqs. (14)-(17)", fontsize=10)

    ax = axes[1]
    p, l = np.array([0.0, 0.0]), np.array([math.sin(0.35), math.cos(0.35)])
    ax.plot(*np.array([p - 0.3 * l, p + 3 * l]).T, color="k", linewidth=3, label="tool shaft (p, l)")
    c = np.array([0.45, 1.9])
    ax.plot(*c, "o", color="tab:red")
    ax.text(c[0] + 0.07, c[1], "port c", color="tab:red")
    foot = p + ((c - p) @ l) * l
    ax.plot(*np.array([foot, c]).T, "--", color="tab:red")
    ax.text(*(0.5 * (foot + c) + [0.05, -0.25]), "|w| = |(c - p) x l|\n= distance to the shaft", color="tab:red",
            fontsize=8)
    circ = np.linspace(0, 2 * np.pi, 100)
    ax.plot(c[0] + 0.25 * np.cos(circ), c[1] + 0.25 * np.sin(circ), color="tab:blue", linewidth=0.8)
    ax.text(c[0] + 0.3, c[1] + 0.2, "eps (n-gon normal to l)", color="tab:blue", fontsize=8)
    ax.plot(*p, "ks")
    ax.text(p[0] + 0.08, p[1] - 0.1, "frame origin p")
    ax.set_aspect("equal")
    ax.set_xlim(-1.5, 2.5), ax.set_ylim(-0.5, 3.2)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("passes_through(port): (c - p) x l = 0 within eps (lecture slide 46)", fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / "plane_and_port.png", dpi=DPI)
    plt.close(fig)


def figure_rotation_polygons():
    """Which plane each rotation polygon lies in, relative to the tool axis."""
    fig = plt.figure(figsize=(12, 4.4))
    l_t = np.array([0.0, 0.0, 1.0])
    # cone: the tool on a 30 deg cone about l_a; w_d from eq. (22)
    g = math.radians(30)
    l_a = np.array([-math.sin(g), 0.0, math.cos(g)])
    d1 = np.cross(l_t, l_a)
    d1 /= np.linalg.norm(d1)
    d2 = np.cross(d1, l_a)
    d2 /= np.linalg.norm(d2)
    w_cone = math.cos(g) * d2 + math.sin(g) * l_a
    panels = [("keeps_direction (roll-free default)\npolygon normal to l_t: roll is free", l_t, None),
              ("rotates_around(w_d)\npolygon normal to w_d, contains l_t: roll bounded",
               np.array([math.cos(0.4), math.sin(0.4), 0.0]), None),
              ("cone(l_a, 30 deg): w_d of eq. (22)\npolygon contains l_t: roll bounded", w_cone, l_a)]
    for k, (title, normal, axis) in enumerate(panels):
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        normal = normal / np.linalg.norm(normal)
        helper = np.array([1.0, 0, 0]) if abs(normal[0]) < 0.9 else np.array([0, 1.0, 0])
        v1 = np.cross(normal, helper)
        v1 /= np.linalg.norm(v1)
        v2 = np.cross(v1, normal)
        n = 8
        R = 1 / math.cos(math.pi / n)
        a = 2 * np.pi * (np.arange(n + 1) + 0.5) / n
        poly = np.array([R * (math.cos(t) * v1 + math.sin(t) * v2) for t in a])
        ax.add_collection3d(Poly3DCollection([poly[:-1]], alpha=0.25, facecolor="tab:blue", edgecolor="tab:blue"))
        ax.quiver(0, 0, 0, *(1.6 * l_t), color="tab:red", linewidth=2, arrow_length_ratio=0.1)
        ax.text(*(1.7 * l_t), "l_t (tool; roll axis)", color="tab:red", fontsize=8)
        if k:
            ax.quiver(0, 0, 0, *(1.4 * normal), color="k", linewidth=1.5, arrow_length_ratio=0.1)
            ax.text(*(1.5 * normal), "w_d", fontsize=9)
        if axis is not None:
            ax.quiver(0, 0, 0, *(1.5 * axis), color="tab:orange", linewidth=1.5, arrow_length_ratio=0.1)
            ax.text(*(1.6 * axis), "l_a", color="tab:orange", fontsize=9)
        ax.set_title(title, fontsize=9)
        ax.set_xlim(-1.3, 1.3), ax.set_ylim(-1.3, 1.3), ax.set_zlim(-1.3, 1.3)
        ax.set_box_aspect((1, 1, 1))
        ax.set_xticks([]), ax.set_yticks([]), ax.set_zticks([])
        ax.view_init(elev=20, azim=-55)
    fig.suptitle("Rotation polygons act on delta_r + dx_r; a polygon bounds only the components in its plane",
                 fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    fig.savefig(OUT / "rotation_polygons.png", dpi=DPI)
    plt.close(fig)


def main():
    print("sphere polytope (eq. 3):  n x m | listed | unique facets | vertices | farthest vertex / eps")
    for (n, m), listed, unique, far, nv in sphere_table():
        print(f"  {n:>2} x {m:<2} | {listed:>3} | {unique:>3} | {nv:>3} | {far:.4f}")
    print("polygon (eq. 9):  n | vertex / eps = 1 / cos(pi/n)")
    for n in POLYGON_SIDES:
        print(f"  {n:>2} | {1 / math.cos(math.pi / n):.4f}")
    figure_sphere_polytopes()
    figure_polygon_line()
    figure_cone()
    figure_follow_curve()
    figure_plane_port()
    figure_rotation_polygons()
    print("figures written to", OUT)


if __name__ == "__main__":
    main()
