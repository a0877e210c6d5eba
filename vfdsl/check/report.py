"""What ``vfdsl check`` finds, and how it is printed.

A :class:`Finding` has a stable code and name (``VF102 polytope-overshoot``), a severity, the source span
of the construct it is about, a message with the numbers and, where one exists, a suggestion. A
:class:`Report` holds the findings, the table of guaranteed bounds and a few measured figures; it renders
as text (findings grouped per constraint, each printed like a front-end diagnostic with the source line
and a caret, then the bounds table, then a one-line verdict) or as JSON (schema in docs/check.md).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

from vfdsl.errors import EXIT_USER_ERROR, Span, VfError

JSON_SCHEMA_VERSION = 1

# Stable codes: a code never changes meaning; new findings get new codes.
CODES: dict[str, str] = {
    "input-error": "VF000",
    "no-start": "VF001",
    "no-period": "VF002",
    "polytope-unbounded": "VF101",
    "polytope-overshoot": "VF102",
    "polytope-repeated-directions": "VF103",
    "tolerance-nonpositive": "VF201",
    "tolerance-implausible": "VF202",
    "tolerance-below-resolution": "VF203",
    "tolerance-restore-ticks": "VF204",
    "speed-implausible": "VF205",
    "start-infeasible": "VF301",
    "residual-far": "VF401",
    "residual-outside": "VF402",
    "soft-unmet-at-start": "VF403",
    "handsoff-drift": "VF501",
    "kinematics-near-singular": "VF601",
    "frame-fixed": "VF602",
    "start-near-limit": "VF603",
    "start-outside-limits": "VF604",
    "port-lever-short": "VF605",
    "sampled-summary": "VF700",
    "sampled-infeasible": "VF701",
    "sampled-ill-conditioned": "VF702",
    "unused-declaration": "VF801",
    "redundant-constraint": "VF802",
    "contradictory-tolerances": "VF803",
    "inactive-constraint": "VF804",
    "weights-span": "VF805",
    "mesh-start-clearance": "VF901",
    "mesh-open": "VF902",
    "mesh-degenerate": "VF903",
    "mesh-inverted": "VF904",
    "mesh-extent": "VF905",
    "mesh-margin-linearization": "VF906",
    "procedure-not-compiled": "VF950",
    "phase-unreachable": "VF951",
    "phase-dead-end": "VF952",
    "guards-overlap": "VF953",
    "monitor-never-true": "VF954",
    "monitor-always-true": "VF955",
    "entry-unfunnelled": "VF956",
    "entry-always-violated": "VF957",
    "every-phase-fixtures": "VF958",
    "fixture-loosened": "VF959",
    "captured-direction": "VF960",
    "haptic-passivity": "VF970",
    "teleop-workspace": "VF971",
    "teleop-anchor-kept": "VF972",
    "teleop-anchor-swapped": "VF973",
}


class Severity(str, enum.Enum):
    ERROR = "error"        # the fixture is not sound: exit status 1
    WARNING = "warning"    # worth a look; exit status 1 only under --strict
    NOTE = "note"          # information (what the fixture does), never changes the exit status


@dataclass(frozen=True)
class Finding:
    """One result of an analysis. ``subject`` groups findings in the text output (a constraint, a
    declaration or the task); ``data`` carries the numbers for ``--json`` (SI units)."""

    name: str
    severity: Severity
    message: str
    span: Span | None = None
    suggestion: str | None = None
    subject: str = "task"
    data: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()      # e.g. where the params a constraint reads are declared and set

    @property
    def code(self) -> str:
        return CODES[self.name]

    def render(self) -> str:
        """file:line:col, severity and code, message, the source line with a caret, the suggestion."""
        diagnostic = VfError(self.message, self.span, hint=self.suggestion,
                             notes=self.notes)
        return diagnostic.render(f"{self.severity.value} {self.code} {self.name}")

    def to_json(self) -> dict:
        span = self.span
        return {"code": self.code, "name": self.name, "severity": self.severity.value,
                "message": self.message, "suggestion": self.suggestion, "subject": self.subject,
                "location": None if span is None else {"file": span.file, "line": span.line,
                                                        "column": span.column, "end_line": span.end_line,
                                                        "end_column": span.end_column},
                "data": _finite(self.data), "notes": list(self.notes)}


@dataclass(frozen=True)
class Bound:
    """A row of the guaranteed-bounds table: the worst error a constraint's rows admit.

    ``stated`` is the tolerance (or distance, or speed) written in the task, ``worst`` the largest error
    the polytope actually allows (its circumradius), both in SI units of ``kind``."""

    subject: str
    where: str                   # source line (and use sites): "fixtures.vf:10 via task.vf:18"
    kind: str                    # length, angle, speed, angular_speed
    stated: float
    resolution: str              # "4x4", "8", "exact" or "exact (tangent plane)"
    facets: int | None
    worst: float

    def to_json(self) -> dict:
        return {"subject": self.subject, "where": self.where, "kind": self.kind,
                "stated": self.stated, "resolution": self.resolution, "facets": self.facets,
                "worst": _finite(self.worst)}


@dataclass
class Report:
    task: str | None                                   # None when the files did not load
    file: str
    findings: list[Finding] = field(default_factory=list)
    bounds: list[Bound] = field(default_factory=list)
    figures: dict = field(default_factory=dict)        # measured numbers (margins, drift, timings), SI

    @classmethod
    def input_error(cls, file: str, error: VfError) -> "Report":
        """The report of a check that could not run: a usage, parse or semantic error in the files (or a
        value the analyses cannot hold), each of the file's errors a finding VF000 with its position, hint,
        notes and, in ``data``, its front-end code (``error_code``: E201, ...; None for one without)."""
        return cls(None, str(file), [Finding("input-error", Severity.ERROR, e.message, e.pos, e.hint,
                                             data={"error_code": e.code}, notes=e.notes) for e in error.errors])

    def add(self, findings) -> None:
        self.findings.extend(findings)

    def count(self, severity: Severity) -> int:
        return sum(f.severity == severity for f in self.findings)

    def exit_status(self, strict: bool = False) -> int:
        """0 when sound; 1 when a finding is an error (or, under ``strict``, a warning); 2 when the check could
        not run (VF000), as for any error in the files."""
        if any(f.name == "input-error" for f in self.findings):
            return EXIT_USER_ERROR
        bad = self.count(Severity.ERROR) + (self.count(Severity.WARNING) if strict else 0)
        return 1 if bad else 0

    def verdict(self, strict: bool = False) -> str:
        errors, warnings, notes = (self.count(s) for s in Severity)
        counts = f"{errors} error{'s' * (errors != 1)}, {warnings} warning{'s' * (warnings != 1)}, " \
                 f"{notes} note{'s' * (notes != 1)}"
        if self.exit_status(strict):
            why = "errors" if errors else "warnings under --strict"
            return f"{self.task}: NOT SOUND ({counts}; {why})"
        return f"{self.task}: sound ({counts})"

    # ---------------------------------------------------------------------------------- rendering
    def render_text(self, strict: bool = False) -> str:
        out = [f"checking {self.task} ({self.file})", ""]
        groups: dict[str, list[Finding]] = {}
        order = {Severity.ERROR: 0, Severity.WARNING: 1, Severity.NOTE: 2}
        for finding in self.findings:
            groups.setdefault(finding.subject, []).append(finding)
        for subject, findings in groups.items():
            out.append(f"== {subject}")
            for finding in sorted(findings, key=lambda f: order[f.severity]):
                out.append(finding.render())
                out.append("")
        if self.bounds:
            out.append("guaranteed bounds (the worst error each constraint's rows admit)")
            out.extend(_bounds_table(self.bounds))
            out.append("")
        measured = _measured(self.figures)
        if measured:
            out.append("measured")
            out.extend(measured)
            out.append("")
        out.append(self.verdict(strict))
        return "\n".join(out)

    def to_json(self, strict: bool = False) -> dict:
        return {"schema": JSON_SCHEMA_VERSION, "task": self.task, "file": self.file,
                "sound": self.exit_status(strict) == 0, "exit_status": self.exit_status(strict),
                "counts": {s.value: self.count(s) for s in Severity},
                "findings": [f.to_json() for f in self.findings],
                "bounds": [b.to_json() for b in self.bounds],
                "figures": _finite(self.figures)}


def _bounds_table(bounds: list[Bound]) -> list[str]:
    header = ("constraint", "line", "stated", "resolution", "facets", "worst admitted")
    rows = [header]
    for b in bounds:
        ratio = "" if b.worst == b.stated or not math.isfinite(b.worst) else f" (+{b.worst / b.stated - 1:.0%})"
        rows.append((b.subject, b.where, quantity(b.stated, b.kind),
                     b.resolution, "-" if b.facets is None else str(b.facets),
                     quantity(b.worst, b.kind) + ratio))
    widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
    return ["  " + "  ".join(cell.ljust(w) for cell, w in zip(r, widths)).rstrip() for r in rows]


def _measured(figures: dict) -> list[str]:
    """The figures a reader wants next to the findings: margin at the start, each frame's Jacobian, each port's
    lever and sideways speed, the hands-off motion, the time the check took."""
    lines = []
    if "start_margin" in figures:
        lines.append(f"  feasibility margin at the start: {figures['start_margin'] + 0.0:.3g} (m or rad)")   # -0 as 0
    for name, f in figures.get("frames", {}).items():
        lines.append(f"  frame {name}: Jacobian rank {f['rank']}, smallest singular value {f['sigma_min_v']:.3g} "
                     f"(J_v, ratio {f['conditioning_v']:.3g}), {f['sigma_min_w']:.3g} (J_w, ratio "
                     f"{f['conditioning_w']:.3g})")
    for name, f in figures.get("levers", {}).items():
        lines.append(f"  port of {name}: lever {quantity(f['lever'], 'length')}, sideways at most "
                     f"{quantity(f['sideways_speed'], 'speed')} within the joint speed limits ({f['joint']} binds most; "
                     f"{quantity(f['free_speed'], 'speed')} without the port)")
    for name, f in figures.get("hands_off", {}).items():
        lines.append(f"  hands off, frame {name}: moves {quantity(f['moved'], 'length')}, turns "
                     f"{quantity(f['turned'], 'angle')}")
    if "seconds" in figures:
        lines.append(f"  checked in {figures['seconds']:.2f} s")
    return lines


def quantity(value: float, kind: str) -> str:
    """An SI value in the unit a person reads best: um/mm/m for lengths, deg (and mrad) for angles."""
    if not math.isfinite(value):
        return "unbounded"
    if kind in ("length", "speed"):
        per = "/s" if kind == "speed" else ""
        magnitude = abs(value)
        if magnitude >= 1:
            return f"{value:.4g} m{per}"
        if magnitude >= 1e-3 or magnitude == 0:
            return f"{value * 1e3:.4g} mm{per}"
        return f"{value * 1e6:.4g} um{per}"
    if kind in ("angle", "angular_speed"):
        per = "/s" if kind == "angular_speed" else ""
        if abs(value) < math.radians(0.1) and value != 0:
            return f"{value * 1e3:.4g} mrad{per}"
        return f"{math.degrees(value):.4g} deg{per}"
    if kind == "time":
        return f"{value * 1e3:.4g} ms" if abs(value) < 1 else f"{value:.4g} s"
    return f"{value:.4g}"


def _finite(value):
    """JSON has no inf or NaN: they become null (documented)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value
