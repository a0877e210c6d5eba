"""Reading a mesh file (STL, OBJ, PLY through trimesh) into SI units.

The numbers in a mesh file carry no unit. A ``mesh`` param states it: ``param m : mesh(unit = 1 mm) = "a.stl"``
reads one file unit as 1 mm; without ``unit``, a file unit is the task's default length unit (its ``units`` line,
metres when it has none). A mesh in mm read as metres is the classic mistake: an extent (the largest side of the
bounding box) outside [MIN_EXTENT, MAX_EXTENT] is refused with a hint naming both readings (:class:`MeshExtentError`,
before any arithmetic in the stated unit).

A mesh holds at most ``limits.MESH_TRIANGLES`` triangles (its file at most ``limits.MESH_FILE_BYTES``): a
larger one is refused (:class:`MeshSizeError`) before any work on it. A path that cannot be read as a regular file
(missing, a directory, a device, a symlink loop, a name too long) is a :class:`MeshFileError` naming why.

Vertices are merged (STL repeats them per triangle), triangles whose area is below DEGENERATE_AREA (they have no
normal) and repeated triangles are dropped; :class:`MeshData` keeps their counts for ``vfdsl check``.
"""

from __future__ import annotations

import errno
import functools
import hashlib
import io
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vfdsl import limits

MIN_EXTENT = 0.5e-3
"""m: a structure smaller than half a millimetre is not anatomy a fixture can use (a file in metres read as mm)."""
MAX_EXTENT = 2.0
"""m: larger than a patient (a file in mm read as metres)."""
DEGENERATE_AREA = 1e-14
"""m^2 (a triangle of sides ~0.1 um): no reliable normal."""
FORMATS = (".stl", ".obj", ".ply")


class MeshFileError(ValueError):
    """The file is missing, unreadable, empty or of an unsupported format (the caller adds the position)."""


class MeshSizeError(MeshFileError):
    """The mesh has more triangles than ``limits.MESH_TRIANGLES`` (or its file more bytes than ``MESH_FILE_BYTES``)."""


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


def file_digest(content: bytes, unit: float) -> str:
    """The identity of a mesh: its file's bytes and its unit."""
    return hashlib.sha256(content + repr(float(unit)).encode()).hexdigest()


def read_mesh(path: str | Path, unit: float) -> MeshData:
    """The mesh at ``path`` with one file unit = ``unit`` metres; raises MeshFileError. The format is that of the
    name given (a symlink's target may have none, as in content-addressed stores)."""
    path = Path(path).absolute()
    if path.suffix.lower() not in FORMATS:
        raise MeshFileError(f"{path.name}: unsupported mesh format '{path.suffix}' (use STL, OBJ or PLY)")
    try:
        info = path.stat()
    except FileNotFoundError:
        raise MeshFileError(f"mesh file {path} not found" + (" (a symlink to a missing file)"
                                                            if path.is_symlink() else "")) from None
    except (OSError, ValueError) as exc:     # ValueError: a NUL in the name
        reason = ("a symlink loop" if getattr(exc, "errno", None) == errno.ELOOP
                  else getattr(exc, "strerror", None) or str(exc))
        raise MeshFileError(f"cannot read the mesh file {path}: {reason}") from None
    if stat.S_ISDIR(info.st_mode):
        raise MeshFileError(f"{path} is a directory, not a mesh file")
    if not stat.S_ISREG(info.st_mode):
        raise MeshFileError(f"{path} is not a regular file (a device, a pipe or a socket)")
    if info.st_size > limits.MESH_FILE_BYTES:
        raise MeshSizeError(f"{path.name} is {info.st_size:,} bytes, more than a mesh of {limits.MESH_TRIANGLES:,} "
                            f"triangles takes in any format: the limit is {limits.MESH_FILE_BYTES:,} bytes")
    return _read(path, float(unit), info.st_mtime_ns, info.st_size)


@functools.lru_cache(maxsize=16)
def _read(path: Path, unit: float, _mtime: int, _size: int) -> MeshData:
    import trimesh

    try:
        content = path.read_bytes()
    except OSError as exc:
        raise MeshFileError(f"cannot read the mesh file {path}: {exc.strerror}") from None
    try:
        loaded = trimesh.load(io.BytesIO(content), file_type=path.suffix[1:].lower(), force="mesh", process=False)
    except Exception as exc:    # trimesh raises many types for a damaged file
        raise MeshFileError(f"cannot read {path.name} as a mesh: {exc}") from None
    raw = np.asarray(loaded.vertices, dtype=float)
    triangles = np.asarray(loaded.faces, dtype=np.int64)
    if len(triangles) > limits.MESH_TRIANGLES:
        raise MeshSizeError(f"{path.name} has {len(triangles):,} triangles: the limit is {limits.MESH_TRIANGLES:,}")
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
    with np.errstate(invalid="ignore", divide="ignore"):       # a flat patch: trimesh divides by its zero volume
        volume = float(mesh.volume)
    return MeshData(vertices=vertices, triangles=triangles, sha256=file_digest(content, unit), degenerate=degenerate,
                    duplicate=duplicate, watertight=bool(mesh.is_watertight),
                    winding_consistent=bool(mesh.is_winding_consistent), volume=volume)


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
