"""A mesh's proximity query as C (its tables as static arrays + ``query.c``) and as a CasADi external.

One C source per (mesh, K): ``<cache>/meshes/<name>/<name>.c``, with ``name = vfmesh_<digest>_k<K>`` from the mesh
file's digest, the query's text, the tables builder's text and the constants, so a source is written (tables built)
once. The interpreted path calls ``casadi.external(name, lib<name>-<level>.so)``, compiled from that source beside it
with the flags of :mod:`vfdsl.codegen.build` at $VFDSL_OPTIMIZE's level (``task_flags``: one library per level, the
source shared); the generated path compiles the same source into the task's library
(``build_library(..., extra_sources=...)``), where CasADi's generated code calls the symbol ``name`` directly.
Both need a C compiler: without one, :class:`~vfdsl.codegen.build.CompilerUnavailable` (the query has no
CasADi form).

The external's outputs are data for the rows: CasADi is never asked for their derivatives.
"""

from __future__ import annotations

import functools
import hashlib
import os
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from vfdsl.codegen.build import CompilerUnavailable, default_cache_dir, find_compiler, task_flags
from vfdsl.errors import VfError
from vfdsl.mesh.load import MeshData
from vfdsl.mesh.tables import LEAF, build_tables

QUERY = Path(__file__).with_name("query.c")
BUILDER = Path(__file__).with_name("tables.py")   # the tables' builder: a cached query is keyed by its text too
SIMILAR = 0.97
"""Two features whose directions u have a cosine above this (14 deg apart) are one row (the nearer)."""


@dataclass(frozen=True)
class MeshQuery:
    name: str
    source: Path          # the C source (tables + query)
    function: ca.Function  # (a[3], b[3], [cutoff, side]) -> (d[K], s[K], u[3 x K])
    k: int


def query_name(mesh: MeshData, k: int) -> str:
    text = f"{mesh.sha256}|{QUERY.read_text()}|{BUILDER.read_text()}|{k}|{SIMILAR}|{LEAF}"
    key = hashlib.sha256(text.encode()).hexdigest()
    return f"vfmesh_{key[:16]}_k{k}"


def mesh_query(mesh: MeshData, k: int, cache_dir: Path | None = None) -> MeshQuery:
    """The query of ``mesh`` with ``k`` rows, compiled (or found in the cache) and loaded."""
    name = query_name(mesh, k)
    return _load(name, mesh, k, Path(cache_dir or default_cache_dir()) / "meshes")


@functools.lru_cache(maxsize=16)
def _cached(name: str, library_name: str, root: Path) -> tuple[Path, Path] | None:
    source, library = root / name / f"{name}.c", root / name / library_name
    return (source, library) if source.is_file() and library.is_file() else None


def _load(name: str, mesh: MeshData, k: int, root: Path) -> MeshQuery:
    flags = task_flags()
    library_name = f"lib{name}-{flags[0].lstrip('-')}.so"
    found = _cached(name, library_name, root)
    if found is not None:
        try:
            return MeshQuery(name, found[0], ca.external(name, str(found[1])), k)
        except RuntimeError:
            _cached.cache_clear()
    compiler = find_compiler()
    root.mkdir(parents=True, exist_ok=True)
    published = root / name / f"{name}.c"     # the same text at every level: written (its tables built) once
    with tempfile.TemporaryDirectory(dir=root, prefix=f".build-{name}-") as tmp:
        work = Path(tmp) / name
        work.mkdir()
        (work / f"{name}.c").write_text(published.read_text() if published.is_file() else c_source(name, mesh, k))
        argv = [*compiler.command, *flags, "-shared", f"{name}.c", "-o", library_name, "-lm"]
        result = subprocess.run(argv, cwd=work, capture_output=True, text=True)
        if result.returncode != 0:
            raise VfError(f"the C compiler failed on the mesh query {name}: {result.stderr[-2000:]}")
        try:
            os.replace(work, root / name)       # a new folder: the source and this library at once
        except OSError:                         # the folder is there (another level's library, another process)
            os.replace(work / library_name, root / name / library_name)
    _cached.cache_clear()
    found = _cached(name, library_name, root)
    if found is None:
        raise CompilerUnavailable(f"the mesh query {name} could not be published in {root}")
    return MeshQuery(name, found[0], ca.external(name, str(found[1])), k)


def _array(ctype: str, name: str, values: np.ndarray, fmt: str) -> str:
    flat = values.reshape(-1)
    body = ",".join(fmt % x for x in flat.tolist())
    return f"static const {ctype} {name}[{max(len(flat), 1)}] = {{{body or '0'}}};\n"


def c_source(name: str, mesh: MeshData, k: int) -> str:
    """The self-contained C source of the query of ``mesh`` (exported symbols: ``name``, ``name_n_in``, ...)."""
    t = build_tables(mesh.vertices, mesh.triangles)
    head = (f"/* {name}: proximity query of a mesh of {len(t.triangles)} triangles, {len(t.vertices)} vertices "
            f"(metres, the mesh's frame); BVH of {len(t.nodes)} nodes, depth {t.depth}. Generated by vfdsl. */\n"
            f"#define VFM_NV {len(t.vertices)}\n#define VFM_NT {len(t.triangles)}\n#define VFM_K {k}\n"
            f"#define VFM_LEAF {LEAF}\n#define VFM_SIMILAR {SIMILAR!r}\n")
    tables = "".join([
        _array("double", "vfm_vertices", t.vertices, "%.17g"),
        _array("int", "vfm_triangles", t.triangles, "%d"),
        _array("float", "vfm_face_normals", t.face_normals, "%.9g"),
        _array("float", "vfm_edge_normals", t.edge_normals, "%.9g"),
        _array("float", "vfm_vertex_normals", t.vertex_normals, "%.9g"),
        _array("int", "vfm_nodes", t.nodes, "%d"),
        _array("double", "vfm_boxes", t.boxes, "%.17g"),
        _array("int", "vfm_leaf_vertices", t.leaf_vertices, "%d"),
        _array("unsigned char", "vfm_corner_slots", t.corner_slots, "%d"),
    ])
    return head + tables + QUERY.read_text().replace("@NAME@", name)
