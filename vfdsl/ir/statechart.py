"""A task's phase machine as a statechart, in Graphviz DOT or Mermaid (``vfdsl show --statechart``).

States are the phases (the initial one entered from a start mark, final ones doubly outlined in DOT and leading
to the end mark in Mermaid); each transition is an edge labelled ``ORDER: GUARD`` with the guard as written
(ORDER: its place in the file, the first whose guard holds fires), and its blend time when it has one. A
transition from ``*`` is drawn from every phase it can leave: every phase but the final ones and its target.
"""

from __future__ import annotations

from vfdsl.ir import model as ir


def edges(task: ir.Task) -> list[tuple[str, str, str]]:
    """(source, target, label) of every transition, ``*`` expanded, in file order."""
    out = []
    for t in task.transitions:
        sources = [t.source] if t.source is not None else \
            [p.name for p in task.phases if not p.final and p.name != t.target]
        label = f"{t.order + 1}: {t.text}" + (f" (blend {t.blend * 1e3:g} ms)" if t.blend else "")
        out.extend((source, t.target, label) for source in sources)
    return out


def dot(task: ir.Task) -> str:
    lines = [f'digraph "{_quoted(task.name)}" {{', "  rankdir=LR;", "  node [shape=box, style=rounded];",
             '  "__start" [shape=point, label=""];']
    for phase in task.phases:
        extra = ", peripheries=2" if phase.final else ""
        lines.append(f'  "{phase.name}" [label="{phase.name}"{extra}];')
        if phase.initial:
            lines.append(f'  "__start" -> "{phase.name}";')
    lines += [f'  "{a}" -> "{b}" [label="{_quoted(label)}"];' for a, b, label in edges(task)]
    return "\n".join(lines + ["}"]) + "\n"


def mermaid(task: ir.Task) -> str:
    lines = ["stateDiagram-v2"]
    lines += [f"  [*] --> {p.name}" for p in task.phases if p.initial]
    lines += [f"  {a} --> {b} : {_mermaid_text(label)}" for a, b, label in edges(task)]
    lines += [f"  {p.name} --> [*]" for p in task.phases if p.final]
    return "\n".join(lines) + "\n"


def _quoted(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"')


def _mermaid_text(text: str) -> str:
    """A label Mermaid reads as text: its entity codes for the characters it would parse."""
    return text.replace("#", "#35;").replace(";", "#59;").replace("<", "#lt;").replace(">", "#gt;")
