"""Code generation: C source from CasADi Functions, compiled and cached by content hash."""

from vfdsl.codegen.build import (
    BuiltLibrary,
    CompilerUnavailable,
    build_library,
    find_compiler,
)

__all__ = ["BuiltLibrary", "CompilerUnavailable", "build_library", "find_compiler"]
