"""Every edit vfdsl makes to CasADi's generated C, in one function (:func:`patch_generated_c`).

- Conics built with ``error_on_fail=False`` continue after a failed solve when CasADi evaluates
  them, but CasADi's generated C still aborts the whole function (``return -1``). That early return
  is removed, so the generated code has the interpreted semantics (failure reported through the
  outputs, see :mod:`vfdsl.runtime.qp`); conics with ``error_on_fail=True`` (``return -1000``) are
  left alone.
- C99's ``fmax``/``fmin`` are inlined (:data:`INLINE_MIN_MAX`).
- CasADi's DAQP interface (``casadi_daqp_solve``, ``casadi_daqp_free_mem``) is replaced by
  ``daqp_persistent.c``: the DAQP workspace is allocated on a conic's first call and kept, later
  calls update it in place, so a step allocates nothing. Each conic's call follows its
  :class:`~vfdsl.codegen.solve_plan.SolvePlan` (warm or cold start, DAQP's priority levels, their exact solve by
  ``lexls.c``, whose header ``lexls.h`` is prepended to ``daqp_persistent.c`` and whose memory is a pointer added to
  CasADi's DAQP data struct); a conic without a plan is refused.
- Every solver's memory pool answers with the running call's slot (``memory_slots.c``); an external function without
  memory (a mesh query) answers 0, so that a function calling it runs outside the step too (a teleoperated task's
  readout).

The replaced definitions are matched exactly; a CasADi whose generated C differs is refused with an error, never
half-patched. tests/golden/ holds CasADi's C and its patched form for each CasADi version the patterns were made on.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import casadi as ca

from vfdsl.codegen import solve_plan
from vfdsl.codegen.solve_plan import SolvePlan
from vfdsl.errors import VfError

LEXLS_SOURCE, LEXLS_HEADER = Path(__file__).with_name("lexls.c"), Path(__file__).with_name("lexls.h")
PERSISTENT_DAQP = LEXLS_HEADER.read_text() + (Path(__file__).parent / "daqp_persistent.c").read_text()
MEMORY_SLOTS = (Path(__file__).parent / "memory_slots.c").read_text()
MAX_SLOTS = 64
"""Controllers of one task that may exist at once in a process (memory slots of its generated code)."""
INLINE_MIN_MAX = """/* vfdsl: C99's fmax and fmin (a NaN argument ignored, as libm's), inlined: without -ffinite-math-only, which the
   step's NaN checks forbid, GCC calls libm for each (~5 % of a tick, measured on experiment B) */
static inline double vfdsl_fmax(double x, double y) { return (x > y || y != y) ? x : y; }
static inline double vfdsl_fmin(double x, double y) { return (x < y || y != y) ? x : y; }
#define fmax vfdsl_fmax
#define fmin vfdsl_fmin
"""
_REQUIRED = "install the CasADi version vfdsl requires (pip install 'casadi>=3.8.2,<3.9')"
_NONFATAL_FAILURE = re.compile(r"if \(!d_qp\.success\) \{\s*return -1;\s*\}")
_MATH_INCLUDE = "#include <math.h>\n"
_DAQP_SOLVE = re.compile(r"^int casadi_daqp_solve\(struct casadi_daqp_data\* d, [^\n]*\{\n.*?^\}\n",
                         re.MULTILINE | re.DOTALL)
_DAQP_FREE_MEM = re.compile(r"^void casadi_daqp_free_mem\(struct casadi_daqp_data\* d\) \{\n\}\n",
                            re.MULTILINE)
_H = r"\(h(?:\[\d+x\d+\])?,"
"""A conic's first argument in CasADi's comment: h[nxn], or h alone for a 1 x 1 (one variable), which was missed: that
conic kept CasADi's plain DAQP call, without its plan, and the certificate output gave the cost (status 1.04, not 1)."""
_CONIC_CALL = re.compile(r"(/\* (\w+):" + _H + r"[^\n]*\*/\nstatic int \w+\([^\n]*\{\n(?:(?!\n\}\n).)*?)"
                         r"casadi_daqp_solve\(d, arg, res, iw, w\);", re.DOTALL)
_CONIC = re.compile(r"/\* \w+:" + _H)
_DAQP_DATA_END = "  int bnb_itercount;\n};\n"
_MAX_THREADS = "#ifndef CASADI_MAX_NUM_THREADS\n#define CASADI_MAX_NUM_THREADS 1\n#endif\n"
_POOL_CHECKOUT = re.compile(r"^int (casadi_f\d+)_checkout\(void\) \{\n.*?^\}\n", re.MULTILINE | re.DOTALL)
_POOL_RELEASE = re.compile(r"^void (casadi_f\d+)_release\(int mem\) \{\n.*?^\}\n", re.MULTILINE | re.DOTALL)


def patch_generated_c(source: str, prefix: str, plans: Mapping[str, SolvePlan]) -> str:
    """CasADi's generated C of the step exported as ``prefix`` (:func:`vfdsl.codegen.build.casadi_c`), with
    vfdsl's edits (module docstring); ``plans``: the solve plan of each conic, by name."""
    source = _NONFATAL_FAILURE.sub("/* vfdsl: solver failure reported through the outputs */", source)
    if source.count(_MATH_INCLUDE) != 1:
        raise VfError(f"CasADi {ca.__version__} generates C this vfdsl does not know (no single <math.h>)",
                      hint=_REQUIRED)
    source = source.replace(_MATH_INCLUDE, _MATH_INCLUDE + INLINE_MIN_MAX)
    source = _with_persistent_daqp(source, plans)
    return _with_memory_slots(source, prefix)


def _with_persistent_daqp(source: str, plans: Mapping[str, SolvePlan]) -> str:
    """``source`` with CasADi's DAQP interface replaced by ``daqp_persistent.c`` (unchanged if it
    has no DAQP conic)."""
    if "casadi_daqp_solve" not in source:
        return source
    solve, free_mem = _DAQP_SOLVE.findall(source), _DAQP_FREE_MEM.findall(source)
    if len(solve) != 1 or len(free_mem) != 1:
        raise VfError(f"CasADi {ca.__version__} generates a DAQP interface this vfdsl does not know", hint=_REQUIRED)
    source, calls = _CONIC_CALL.subn(lambda match: _conic_call(match, plans), source)
    if calls != len(_CONIC.findall(source)):
        raise VfError(f"CasADi {ca.__version__}: a conic's DAQP call was not found")
    if source.count(_DAQP_DATA_END) != 1:
        raise VfError(f"CasADi {ca.__version__} generates DAQP data this vfdsl does not know", hint=_REQUIRED)
    source = source.replace(_DAQP_DATA_END, _DAQP_DATA_END.replace("};", "  struct vfdsl_lex* lex;    /* vfdsl: lexls.c's memory */\n};"))
    source = _DAQP_FREE_MEM.sub("", source)
    persistent = PERSISTENT_DAQP.replace("@ITER_LIMIT@", str(solve_plan.ITER_LIMIT))   # read now: tests lower it
    return _DAQP_SOLVE.sub(lambda _: persistent, source)


def _conic_call(match: re.Match, plans: Mapping[str, SolvePlan]) -> str:
    """The DAQP call of one conic, as its plan says."""
    body, name = match.group(1), match.group(2)
    plan = plans.get(name)
    if plan is None:
        raise VfError(f"the generated C calls DAQP in a conic {name!r} that has no solve plan")
    if not plan.break_points:
        return f"{body}vfdsl_daqp_solve(d, {int(plan.warm_start)}, 0);"
    points = plan.break_points
    table = (f"static const vfdsl_levels levels = {{{len(points)}, {_c_double(plan.rho)}, {int(plan.partial)}, "
             f"{int(plan.exact)}, {int(plan.start)}, {{{', '.join(map(str, points))}}}}};")
    return f"{body}{{\n    {table}\n    vfdsl_daqp_solve(d, {int(plan.warm_start)}, &levels);\n  }}"


def _c_double(value: float) -> str:
    """``value`` as the shortest C literal that reads back as the same double (``1e-6``, not ``1e-06``)."""
    mantissa, _, exponent = repr(float(value)).partition("e")
    return f"{mantissa}e{int(exponent)}" if exponent else mantissa


def _with_memory_slots(source: str, prefix: str) -> str:
    """``source`` with one memory slot per caller (``memory_slots.c``): the exported checkout/release
    hand out slots, and every solver's memory pool answers with the running call's slot."""
    entry = (f"CASADI_SYMBOL_EXPORT int {prefix}(const casadi_real** arg, casadi_real** res, "
             f"casadi_int* iw, casadi_real* w, int mem){{\n  return casadi_f0(arg, res, iw, w, mem);\n}}\n\n"
             f"CASADI_SYMBOL_EXPORT int {prefix}_checkout(void) {{\n  return 0;\n}}\n\n"
             f"CASADI_SYMBOL_EXPORT void {prefix}_release(int mem) {{\n}}\n")
    checkouts = _POOL_CHECKOUT.findall(source)
    pools = [f for f in checkouts if f"{f}_init_mem" in source]   # external functions (mesh queries) have no memory
    if source.count(entry) != 1 or source.count(_MAX_THREADS) != 1 or len(_POOL_RELEASE.findall(source)) != len(checkouts):
        raise VfError(f"CasADi {ca.__version__} generates an entry point this vfdsl does not know", hint=_REQUIRED)
    source = source.replace(_MAX_THREADS, f"#define CASADI_MAX_NUM_THREADS {MAX_SLOTS}\n"
                            "#define VFDSL_MAX_SLOTS CASADI_MAX_NUM_THREADS\n"
                            "static int vfdsl_current_slot(void);\n")
    source = _POOL_CHECKOUT.sub(lambda m: f"int {m.group(1)}_checkout(void) {{\n  return "
                                          f"{'vfdsl_current_slot()' if m.group(1) in pools else '0'};\n}}\n", source)
    source = _POOL_RELEASE.sub(r"void \1_release(int mem) {\n}\n", source)
    slots = (MEMORY_SLOTS.replace("@PREFIX@", prefix)
             .replace("@INIT_SLOT@", "\n".join(f"  {pool}_init_mem(s);" for pool in pools))
             .replace("@FREE_SLOT@", "\n".join(f"  {pool}_free_mem(s);\n  memset(&{pool}_mem[s], 0, sizeof {pool}_mem[s]);"
                                                for pool in pools)))
    return source.replace(entry, slots)
