"""The tables of docs/results.md, generated: every figure in them comes from the runs defined here.

    python docs/results_tables.py            # run every simulation (about a minute on one core), write
                                             # docs/results_tables.json, rewrite the tables in results.md
    python docs/results_tables.py --render   # rewrite the tables in results.md from the JSON (no simulation)
    python docs/results_tables.py --check    # compare results.md with the JSON (no simulation)

The JSON holds, for every run, its settings and each trial's statistics (count, mean, sum of squared
deviations, max of every metric, in the summary's units), so a table cell is the trials merged in order,
as ``vfdsl simulate`` pools them. The page holds each table between ``<!-- table NAME -->`` and
``<!-- /table -->``; ``tests/test_results_tables.py`` checks that the page is this script's rendering of the JSON,
that the JSON's cells are the merge of its trials, and, rerunning the first trial of every run short
enough for a test, that the JSON is what the code gives now.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import sys
from pathlib import Path

import vfdsl
from vfdsl.sim.metrics import Stats
from vfdsl.sim.runner import make_jobs, run
from vfdsl.sim.scene_file import load_settings

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "results.md"
DATA = ROOT / "docs" / "results_tables.json"
A = "tasks/paper_a_follow_curve.vf"
B = "tasks/paper_b_virtual_rcm.vf"
A_SCENE = "tasks/paper_a_follow_curve.sim.yaml"
B_SCENE = "tasks/paper_b_virtual_rcm.sim.yaml"
VESSEL = "tasks/breathing_vessel.vf"
VESSEL_SCENE = "tasks/breathing_vessel.sim.yaml"
PERIODS = (0.15, 0.04, 0.01, 0.001)
LATENCIES = (0.0, 0.14, 0.3, 0.45)
HAND_SPEEDS = (2.5, 5.0, 10.0)            # mm/s: the hand's force in N at A's 1 mm/s/N
A_DURATION = 24.0                          # s at 5 mm/s: each trial covers the curve and stops at its end


@dataclasses.dataclass(frozen=True)
class Run:
    task: str
    scene: str
    settings: tuple = ()                   # (name, SI value) changed from the scene
    hand_magnitude: float | None = None    # the scene hand's magnitude, SI

    def simulate(self, trials: int | None = None) -> list:
        task = vfdsl.load(ROOT / self.task)
        settings = load_settings(task, ROOT / self.scene).replace(**dict(self.settings))
        if self.hand_magnitude is not None:
            settings = dataclasses.replace(settings, hand=dataclasses.replace(settings.hand,
                                                                              magnitude=self.hand_magnitude))
        if trials is not None:
            settings = settings.replace(trials=trials)
        return run(make_jobs(str(ROOT / self.task), settings), workers=1)

    def ticks_per_trial(self) -> int:
        task = vfdsl.load(ROOT / self.task)
        s = load_settings(task, ROOT / self.scene).replace(**dict(self.settings))
        return round(s.duration / s.period)


def runs() -> dict[str, Run]:
    out = {"A": Run(A, A_SCENE), "B": Run(B, B_SCENE), "vessel": Run(VESSEL, VESSEL_SCENE),
           "B_ideal": Run(B, B_SCENE, (("resolution", "off"), ("noise", 0.0), ("duration", 20.0), ("trials", 1)))}
    for period in PERIODS:
        for resolution in ("robot", "off"):
            out[f"A_period_{period * 1e3:g}ms_{resolution}"] = Run(
                A, A_SCENE, (("period", period), ("latency", 0.0), ("noise", 0.0), ("resolution", resolution)))
    for latency in LATENCIES:
        out[f"A_latency_{latency * 1e3:g}ms"] = Run(A, A_SCENE, (("latency", latency), ("noise", 0.0)))
    for speed in HAND_SPEEDS:
        out[f"A_hand_{speed:g}mm_s"] = Run(A, A_SCENE, (("duration", A_DURATION * 5.0 / speed),), speed)
    return out


def trial_record(result) -> dict:
    return {"trial": result.trial, "seed": result.seed, "ticks": result.ticks, "fallback_ticks": result.fallback_ticks,
            "stats": {name: [s.count, s.mean, s.squares, s.worst] for name, s in result.stats.items()}}


def generate() -> dict:
    data = {}
    for name, r in runs().items():
        print(f"{name} ...", file=sys.stderr)
        data[name] = {"task": r.task, "scene": r.scene, "settings": dict(r.settings),
                      "hand_magnitude": r.hand_magnitude, "trials": [trial_record(t) for t in r.simulate()]}
    return data


# ------------------------------------------------------------------------------------------------- tables
def pooled(data: dict, run: str, metric: str) -> Stats:
    total = Stats()
    for trial in sorted(data[run]["trials"], key=lambda t: t["trial"]):
        total = total.merge(Stats(*trial["stats"][metric]))
    return total


def fallback(data: dict, run: str) -> tuple[int, int]:
    return (sum(t["fallback_ticks"] for t in data[run]["trials"]), sum(t["ticks"] for t in data[run]["trials"]))


def _g(x: float) -> str:
    return f"{x:.2g}"


def cell(stats: Stats, unit: str, worst: str = "max") -> str:
    return f"{_g(stats.mean)} ± {_g(stats.std)} {unit} ({worst} {_g(stats.worst)})"


def tables(data: dict) -> dict[str, str]:
    p = lambda run, metric: pooled(data, run, metric)  # noqa: E731
    out = {}
    out["side_by_side"] = "\n".join([
        "| | paper | vfdsl, robot kinematics (\"encoders\") | vfdsl, simulated tracker (0.2 mm RMS) |",
        "|---|---|---|---|",
        f"| A: tip error to the curve, 150 ms loop | 0.32 ± 0.19 mm (optical tracker) | "
        f"{cell(p('A', 'tip_error_mm'), 'mm')} | {cell(p('A', 'tracker_tip_error_mm'), 'mm')} |",
        f"| B: pivot position error, 10 ms loop | 0.01 ± 0.01 mm (encoders), 0.23 ± 0.11 mm (tracker) | "
        f"{cell(p('B', 'pivot_error_mm'), 'mm')} | {cell(p('B', 'tracker_pivot_error_mm'), 'mm')} |",
        f"| B: tool angle error, 10 ms loop | 0.03 ± 0.02 deg (encoders), 0.09 ± 0.06 deg (tracker) | "
        f"{cell(p('B', 'tool_angle_error_deg'), 'deg')} | {cell(p('B', 'tracker_tool_angle_error_deg'), 'deg')} |"])
    rows = ["| period | joint resolution of the SHR | no joint resolution |", "|---|---|---|"]
    for period in PERIODS:
        key = f"A_period_{period * 1e3:g}ms"
        rows.append(f"| {period * 1e3:g} ms | {cell(p(key + '_robot', 'tip_error_mm'), 'mm', 'worst')} | "
                    f"{cell(p(key + '_off', 'tip_error_mm'), 'mm', 'worst')} |")
    out["periods"] = "\n".join(rows)
    rows = ["| latency | tip error by the encoders | ticks on the least-violation fallback |", "|---|---|---|"]
    for latency in LATENCIES:
        key = f"A_latency_{latency * 1e3:g}ms"
        done, ticks = fallback(data, key)
        rows.append(f"| {latency * 1e3:g} ms | {cell(p(key, 'tip_error_mm'), 'mm', 'worst')} | {done} of {ticks} |")
    out["latency"] = "\n".join(rows)
    rows = ["| hand speed (force at 1 mm/s/N) | trial | tip error by the encoders | by the tracker (0.2 mm RMS) |",
            "|---|---|---|---|"]
    for speed in HAND_SPEEDS:
        key = f"A_hand_{speed:g}mm_s"
        rows.append(f"| {speed:g} mm/s ({speed:g} N) | {A_DURATION * 5 / speed:g} s | "
                    f"{cell(p(key, 'tip_error_mm'), 'mm')} | {cell(p(key, 'tracker_tip_error_mm'), 'mm')} |")
    out["hand_speed"] = "\n".join(rows)
    vessel = p("vessel", "vessel_error_mm")
    done, ticks = fallback(data, "vessel")
    out["vessel"] = "\n".join([
        "| run | vessel error: mean | std | max | ticks on the least-violation fallback |", "|---|---|---|---|---|",
        f"| the scene as shipped | {_g(vessel.mean)} mm | {_g(vessel.std)} mm | {_g(vessel.worst)} mm | "
        f"{done} of {ticks} |"])
    pivot, angle = p("B_ideal", "pivot_error_mm"), p("B_ideal", "tool_angle_error_deg")
    done, ticks = fallback(data, "B_ideal")
    out["ideal_b"] = "\n".join([
        "| error | measured max | bound: polytope + linearization |", "|---|---|---|",
        f"| pivot | {pivot.worst * 1e3:.2f} um | 1.73 + 2.7 um |",
        f"| tool angle | {angle.worst:.5f} deg | 0.0642 + 0.003 deg |",
        f"| fallback ticks | {done} of {ticks} | |"])
    return out


# --------------------------------------------------------------------------------------------------- page
BLOCK = re.compile(r"(<!-- table (\w+) -->\n)([^<]*?)\n?(<!-- /table -->)")   # a table holds no '<'


def page_tables(text: str) -> dict[str, str]:
    return {m.group(2): m.group(3) for m in BLOCK.finditer(text)}


def render(text: str, generated: dict[str, str]) -> str:
    missing = set(generated) - set(page_tables(text))
    if missing:
        raise SystemExit(f"results.md has no <!-- table NAME --> block for {', '.join(sorted(missing))}")
    return BLOCK.sub(lambda m: m.group(1) + generated[m.group(2)] + "\n" + m.group(4), text)


def differences(text: str, data: dict) -> list[str]:
    """Tables on the page that are not the rendering of the data (empty: they agree)."""
    on_page, generated = page_tables(text), tables(data)
    out = [f"table {name}: not on the page" for name in generated if name not in on_page]
    out += [f"table {name}: no such table in the script" for name in on_page if name not in generated]
    out += [f"table {name} differs:\n--- page\n{on_page[name]}\n--- script\n{generated[name]}"
            for name in generated if name in on_page and on_page[name] != generated[name]]
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--check", action="store_true", help="compare the page with the JSON; run nothing")
    parser.add_argument("--render", action="store_true", help="rewrite the page's tables from the JSON; run nothing")
    args = parser.parse_args(argv)
    if args.render:
        PAGE.write_text(render(PAGE.read_text(), tables(json.loads(DATA.read_text()))))
        return 0
    if args.check:
        problems = differences(PAGE.read_text(), json.loads(DATA.read_text()))
        print("\n".join(problems) or "results.md agrees with results_tables.json")
        return 1 if problems else 0
    data = generate()
    DATA.write_text(json.dumps(data, indent=1) + "\n")
    PAGE.write_text(render(PAGE.read_text(), tables(data)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
