"""Reading a mesh file (STL, OBJ, PLY through trimesh) into SI units.

The numbers in a mesh file carry no unit. A ``mesh`` param states it: ``param m : mesh(unit = 1 mm) = "a.stl"``
reads one file unit as 1 mm; without ``unit``, a file unit is the task's default length unit (its ``units`` line,
metres when it has none). A mesh in mm read as metres is the classic mistake: an extent (the largest side of the
bounding box) outside [MIN_EXTENT, MAX_EXTENT] is refused with a hint naming both readings (:class:`MeshExtentError`,
before any arithmetic in the stated unit).

Vertices are merged (STL repeats them per triangle), triangles whose area is below DEGENERATE_AREA (they have no
normal) and repeated triangles are dropped; :class:`MeshData` keeps their counts for ``vfdsl check``.
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

MIN_EXTENT = 0.5e-3
"""m: a structure smaller than half a millimetre is not anatomy a fixture can use (a file in metres read as mm)."""
MAX_EXTENT = 2.0
"""m: larger than a patient (a file in mm read as metres)."""
DEGENERATE_AREA = 1e-14
"""m^2 (a triangle of sides ~0.1 um): no reliable normal."""
FORMATS = (".stl", ".obj", ".ply")


class MeshFileError(ValueError):
    """The file is missing, unreadable, empty or of an unsupported format (the caller adds the position)."""


class MeshExtentError(MeshFileError):
    """The mesh's extent in the stated unit is implausible for anatomy: the unit is likely wrong."""


@dataclass(frozen=True, eq=False)
class MeshData:
    """A triangle mesh in metres, in its own frame: vertices (V x 3), triangles (T x 3 vertex indices)."""

    vertices: np.ndarray
    triangles: np.ndarray
    sha256: str                   # of the file's bytes and the unit
    degenerate: int               # triangles dropped for a zero area
    duplicate: int                # triangles dropped as repeats of another (same three vertices)
    watertight: bool              # every edge shared by exactly two triangles
    winding_consistent: bool      # neighbours traverse their shared edge in opposite directions
    volume: float                 # signed volume (m^3), > 0 for outward normals when watertight

    @property
    def extent(self) -> float:
        return float(np.ptp(self.vertices, axis=0).max())


def file_digest(path: Path, unit: float) -> str:
    return hashlib.sha256(path.read_bytes() + repr(float(unit)).encode()).hexdigest()


def read_mesh(path: str | Path, unit: float) -> MeshData:
    """The mesh at ``path`` with one file unit = ``unit`` metres; raises MeshFileError."""
    path = Path(path)
    return _read(path.resolve(), float(unit), path.stat().st_mtime_ns if path.is_file() else 0)


@functools.lru_cache(maxsize=16)
def _read(path: Path, unit: float, _mtime: int) -> MeshData:
    import trimesh

    if path.suffix.lower() not in FORMATS:
        raise MeshFileError(f"{path.name}: unsupported mesh format '{path.suffix}' (use STL, OBJ or PLY)")
    if path.is_dir():
        raise MeshFileError(f"{path} is a directory, not a mesh file")
    if not path.is_file():
        raise MeshFileError(f"mesh file {path} not found")
    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:    # trimesh raises many types for a damaged file
        raise MeshFileError(f"cannot read {path.name} as a mesh: {exc}") from None
    raw = np.asarray(loaded.vertices, dtype=float)
    triangles = np.asarray(loaded.faces, dtype=np.int64)
    if len(triangles) == 0 or not np.all(np.isfinite(raw)):
        raise MeshFileError(f"{path.name} has no triangles or non-finite vertices")
    with np.errstate(over="ignore"):           # (an extent of inf is refused below)
        problem = _extent_problem(float(np.ptp(raw, axis=0).max()), unit)    # before any arithmetic in the unit
    if problem is not None:
        raise MeshExtentError(problem)
    vertices = raw * unit
    vertices, inverse = np.unique(vertices, axis=0, return_inverse=True)
    triangles = inverse.reshape(-1)[triangles]
    area = 0.5 * np.linalg.norm(np.cross(vertices[triangles[:, 1]] - vertices[triangles[:, 0]],
                                         vertices[triangles[:, 2]] - vertices[triangles[:, 0]]), axis=1)
    keep = area > DEGENERATE_AREA
    degenerate = int((~keep).sum())
    triangles = triangles[keep]
    _, first = np.unique(np.sort(triangles, axis=1), axis=0, return_index=True)
    duplicate = len(triangles) - len(first)
    triangles = triangles[np.sort(first)]
    if len(triangles) == 0:
        raise MeshFileError(f"{path.name}: every triangle is degenerate")
    mesh = trimesh.Trimesh(vertices, triangles, process=False)
    return MeshData(vertices=vertices, triangles=triangles, sha256=file_digest(path, unit), degenerate=degenerate,
                    duplicate=duplicate, watertight=bool(mesh.is_watertight),
                    winding_consistent=bool(mesh.is_winding_consistent), volume=float(mesh.volume))


def _extent_problem(file_extent: float, unit: float) -> str | None:
    """None when the mesh's extent (``file_extent`` file units) is plausible for anatomy, else why not (naming the
    other reading)."""
    extent = file_extent * unit
    if extent > MAX_EXTENT:
        return (f"the mesh spans {extent:.4g} m with one file unit = {unit:g} m: larger than a patient "
                f"(in mm it would span {file_extent * 1e-3:.4g} m)")
    if extent < MIN_EXTENT:
        return (f"the mesh spans {extent:.3g} m with one file unit = {unit:g} m: too small for anatomy "
                f"(in m it would span {file_extent:.4g} m)")
    return None
