"""Write the anatomy meshes of the examples (STL, in millimetres): run ``python tasks/anatomy/make_meshes.py``.

- channel.stl: a sinus-like working channel for ``tasks/sinus_channel.vf``, a closed tube of radius RADIUS around
  a centreline that runs down from z = 320 mm and bends toward +x below z = 295 mm (x = BEND ((295 - z) / 65)^2),
  ending at z = 228 mm; capped at both ends, normals outward.
- bone.stl: a bone for ``tasks/bone_nerve.vf``, an ellipsoid (semi-axes 20, 15, 8 mm) centred at (0, 0, 250) mm.
- nerve.stl: a nerve on the bone's top, a closed cylinder of radius 1.5 mm along y at (6, 0, 259) mm.

The meshes are deterministic (no randomness), so the files change only when this script does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).parent
RADIUS = 5.0       # mm
BEND = 10.0        # mm


def tube(centres: np.ndarray, radius: float, sections: int = 32) -> trimesh.Trimesh:
    """A closed tube around a polyline: rings in parallel-transported frames, both ends capped by a fan."""
    tangents = np.gradient(centres, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    normal = np.cross(tangents[0], np.eye(3)[np.argmin(np.abs(tangents[0]))])
    normal /= np.linalg.norm(normal)
    angles = 2 * np.pi * np.arange(sections) / sections
    rings = []
    for centre, tangent in zip(centres, tangents):
        normal = normal - tangent * (normal @ tangent)
        normal /= np.linalg.norm(normal)
        binormal = np.cross(tangent, normal)
        rings.append(centre + radius * (np.cos(angles)[:, None] * normal + np.sin(angles)[:, None] * binormal))
    vertices = np.vstack(rings + [centres[[0, -1]]])
    faces = []
    n = len(centres)
    for i in range(n - 1):
        for j in range(sections):
            a, b = i * sections + j, i * sections + (j + 1) % sections
            faces += [[a, b + sections, b], [a, a + sections, b + sections]]
    first, last = n * sections, n * sections + 1
    for j in range(sections):
        faces.append([first, j, (j + 1) % sections])
        faces.append([last, (n - 1) * sections + (j + 1) % sections, (n - 1) * sections + j])
    mesh = trimesh.Trimesh(vertices, np.array(faces), process=False)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def channel() -> trimesh.Trimesh:
    z = np.linspace(320.0, 228.0, 93)
    x = BEND * (np.clip(295.0 - z, 0, None) / 65.0) ** 2
    return tube(np.column_stack([x, np.zeros_like(z), z]), RADIUS)


def bone() -> trimesh.Trimesh:
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    mesh.apply_scale([20.0, 15.0, 8.0])
    mesh.apply_translation([0.0, 0.0, 250.0])
    return mesh


def nerve() -> trimesh.Trimesh:
    y = np.linspace(-20.0, 20.0, 21)
    return tube(np.column_stack([np.full_like(y, 6.0), y, np.full_like(y, 259.0)]), 1.5, sections=24)


def main() -> None:
    for name, mesh in (("channel", channel()), ("bone", bone()), ("nerve", nerve())):
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0, name
        mesh.export(HERE / f"{name}.stl")
        print(f"{name}.stl: {len(mesh.faces)} triangles, extent {np.ptp(mesh.vertices, axis=0).round(1)} mm")


if __name__ == "__main__":
    main()
