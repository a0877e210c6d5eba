"""``vfdsl export``: a task's controller as a self-contained C library folder (see :mod:`vfdsl.export.writer`).

    from vfdsl.export import export
    result = export(vfdsl.load("tasks/paper_b_virtual_rcm.vf"), "out/")   # out/vf_paper_b_virtual_rcm.h, ...
"""

from __future__ import annotations

from pathlib import Path

from vfdsl.export.writer import Export, api_name, portable, prepare_directory, write_export
from vfdsl.files import path_value, task_sources
from vfdsl.ir import model as ir


def export(task: ir.Task, directory: str | Path, *, cache_dir: str | Path | None = None) -> Export:
    """Generate and build ``task``'s controller (the build cache: ``cache_dir``, default as
    :func:`vfdsl.compile`) and write its folder into ``directory``. Needs a C compiler: the generated C is
    compiled once here, as for :func:`vfdsl.compile`, before it is exported. The task's source paths are made
    relative to its file's folder first (:func:`~vfdsl.export.writer.portable`)."""
    from vfdsl import pipeline
    from vfdsl.codegen.build import daqp_home
    from vfdsl.codegen.daqp_sources import daqp_sources
    task = ir.checked_task(task, "export")
    directory = path_value(directory, "export", "folder to export into", "export(task, 'build/vf_task')")
    if cache_dir is not None:
        cache_dir = path_value(cache_dir, "export", "build cache folder (cache_dir)", "cache_dir='build/'")
    directory = prepare_directory(directory)
    _, library = pipeline.build(portable(task), backend="native", cache_dir=cache_dir)
    return write_export(library, daqp_sources(daqp_home()), directory, task_sources(task))


__all__ = ["Export", "api_name", "export", "write_export"]
