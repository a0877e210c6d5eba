"""The task's tables in C, from a generated library's metadata (:func:`vfdsl.pipeline.metadata`).

Sizes become macros (``NQ``, ``NU``, ``NP``, ``NX``, ``NROWS``, ...) and every list a static array with one
terminating element (C has no empty arrays). Numbers are written with ``repr`` (the shortest decimal that reads
back to the same double) or ``HUGE_VAL``; strings as C literals. Same metadata, same text.
"""

from __future__ import annotations

import math
import re


def c_string(text: str | None) -> str:
    """``text`` as a C string literal (UTF-8; non-ASCII bytes and quotes escaped), or 0 for None."""
    if text is None:
        return "0"
    out = []
    for byte in text.encode():
        char = chr(byte)
        if char in '"\\':
            out.append("\\" + char)
        elif 32 <= byte < 127 and char != "?":        # '?': no trigraphs
            out.append(char)
        else:
            out.append(f"\\{byte:03o}")
    return '"' + "".join(out) + '"'


def comment_text(text: str) -> str:
    """``text`` (e.g. a file path) safe inside a C block comment or a line of text: ``*/`` and ``/*`` written
    ``*\\/`` and ``/\\*``, a ``?`` before another ``?`` followed by ``\\`` (no trigraph), control characters (a
    newline) as ``\\ooo``."""
    text = re.sub(r"\?(?=\?)", "?\\\\", text.replace("*/", "*\\/").replace("/*", "/\\*"))
    return "".join(char if char.isprintable() else f"\\{ord(char):03o}" for char in text)


def c_number(x: float) -> str:
    if math.isinf(x):
        return "HUGE_VAL" if x > 0 else "-HUGE_VAL"
    if math.isnan(x):
        raise ValueError("NaN in a task table")
    return repr(float(x))


def _array(kind: str, name: str, items: list[str]) -> str:
    body = ", ".join([*items, "0"])
    return f"static const {kind} {name}[] = {{{body}}};\n"


def task_tables(meta: dict) -> str:
    """The C declarations @API@.c reads (macros and static arrays), from ``meta``."""
    nq = meta["variables"]["dq"]
    inputs, params, rows, slacks = meta["input_layout"], meta["param_layout"], meta["rows"], meta["slacks"]
    start = meta["start"] or [0.0] * nq
    sizes = {"NQ": nq, "NU": sum(i["size"] for i in inputs), "NP": len(meta["default_params"]),
             "NP_SET": max((p["offset"] + p["size"] for p in params), default=0),   # before the captures
             "NX": nq + meta["variables"]["slack"], "NROWS": len(rows), "NSLACK": len(slacks),
             "NCHECKS": meta["param_checks"]["count"], "NINPUTS": len(inputs), "NPARAMS": len(params)}
    out = [f"#define {name} {value}\n" for name, value in sizes.items()]
    out += [f"#define DEFAULT_PERIOD {c_number(meta['period'] or 0.0)}\n",
            f"#define MIN_PERIOD {c_number(meta['min_period'])}\n",
            f"#define MAX_PERIOD {c_number(meta['max_period'])}\n",
            f"#define DT_RULE {c_string(meta['dt_rule'])}\n",
            f"#define INPUT_RULE {c_string(meta['input_rule'])}\n",
            f"#define FEASIBILITY_TOLERANCE {c_number(meta['feasibility_tolerance'])}\n\n"]
    out += [_array("char* const", "joint_names", [c_string(n) for n in meta["joints"]]),
            _array("char* const", "joint_units", [c_string(u) for u in meta["joint_units"]]),
            _array("double", "q_lower", [c_number(x) for x in meta["q_admissible"]["lower"]]),
            _array("double", "q_upper", [c_number(x) for x in meta["q_admissible"]["upper"]]),
            _array("double", "start", [c_number(x) for x in start]),
            _array("char* const", "input_names", [c_string(i["name"]) for i in inputs]),
            _array("char* const", "input_units", [c_string(i["unit"]) for i in inputs]),
            _array("int", "input_sizes", [str(i["size"]) for i in inputs]),
            _array("char* const", "param_names", [c_string(p["name"]) for p in params]),
            _array("char* const", "param_types", [c_string(p["type"]) for p in params]),
            _array("char* const", "param_units", [c_string(p["unit"]) for p in params]),
            _array("int", "param_offsets", [str(p["offset"]) for p in params]),
            _array("int", "param_sizes", [str(p["size"]) for p in params]),
            _array("double", "p_default", [c_number(x) for x in meta["default_params"]]),
            _array("unsigned char", "strict", [str(int(s)) for s in meta["param_checks"]["strict"]]),
            _array("char* const", "check_meanings", [c_string(m) for m in meta["param_checks"]["meaning"]]),
            _array("int", "check_params", [str(k) for k in meta["param_checks"]["param"]])]
    procedure = meta.get("procedure", {"phases": [], "monitors": [], "transitions": []})
    transitions = procedure["transitions"]
    out += [f"#define NPHASES {len(procedure['phases'])}\n", f"#define NMONITORS {len(procedure['monitors'])}\n",
            f"#define NTRANSITIONS {len(transitions)}\n",
            _array("char* const", "phase_names", [c_string(n) for n in procedure["phases"]]),
            _array("char* const", "monitor_names", [c_string(m["name"]) for m in procedure["monitors"]]),
            _array("int", "monitor_index", [str(m["index"]) for m in procedure["monitors"]]),
            _array("char* const", "transition_guards", [c_string(t["guard"]) for t in transitions]),
            _array("int", "transition_sources", [str(-1 if t["source"] is None else t["source"]) for t in transitions]),
            _array("int", "transition_targets", [str(t["target"]) for t in transitions])]
    out.append("\nstruct row { const char* label; const char* primitive; const char* file; int line; "
               "const char* unit; int soft; };\n")
    for name, table in (("rows", rows), ("slacks", slacks)):
        entries = [f"  {{{c_string(r['label'])}, {c_string(r['primitive'])}, {c_string(r['file'])}, {int(r['line'])}, "
                   f"{c_string(r['unit'])}, {int(r.get('soft', True))}}},\n" for r in table]
        out.append(f"static const struct row {name}[] = {{\n{''.join(entries)}  {{0, 0, 0, 0, 0, 0}}\n}};\n")
    return "".join(out)
