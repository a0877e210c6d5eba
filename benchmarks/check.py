"""How long `vfdsl check` takes on every example task (the sampled analysis included).

    python benchmarks/check.py            # every task in tasks/, cold and warm cache
    python benchmarks/check.py --runs 3   # best of 3 warm runs

Each figure is the wall time of the command as a user runs it (`python -m vfdsl.cli check TASK --json`,
a new process: Python start-up, imports, loading, compiling or reusing the generated controller, every
analysis). "cold" uses a fresh cache directory (the controller's C is generated and compiled) that already
holds DAQP's sources and library, as every run after a machine's first does; "warm" reuses it. The first run
on a fresh machine (an empty cache: DAQP's sources fetched with pip and compiled once) is timed apart, on the
first task. The in-process time of each analysis comes from the report's `figures.timings`.
Progress goes to stderr, the table to stdout; nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BUDGET = 5.0                     # seconds per task, the stated target


def timed_check(task: Path, cache: str) -> tuple[float, dict]:
    env = {**os.environ, "VFDSL_CACHE": cache}
    begin = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "vfdsl.cli", "check", str(task), "--json"], capture_output=True,
                          text=True, env=env, check=False)
    seconds = time.perf_counter() - begin
    if proc.returncode not in (0, 1):
        raise SystemExit(f"vfdsl check {task} failed:\n{proc.stderr}")
    return seconds, json.loads(proc.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=1, help="warm runs per task (the best is shown)")
    args = parser.parse_args()
    tasks = sorted((REPO / "tasks").glob("*.vf"))
    rows = []
    with tempfile.TemporaryDirectory() as machine:
        print(f"[first use] {tasks[0].name}, empty cache", file=sys.stderr, flush=True)
        first, _ = timed_check(tasks[0], machine)
        daqp = next(Path(machine).glob("daqp-*"))
        for k, task in enumerate(tasks, 1):
            print(f"[{k}/{len(tasks)}] {task.name}", file=sys.stderr, flush=True)
            with tempfile.TemporaryDirectory() as cache:
                (Path(cache) / daqp.name).symlink_to(daqp, target_is_directory=True)
                cold, _ = timed_check(task, cache)
                warm = [timed_check(task, cache) for _ in range(args.runs)]
            seconds, report = min(warm, key=lambda r: r[0])
            rows.append((task.stem, cold, seconds, report))
    stages = ["compile", "polytope", "tolerance", "feasibility", "residuals", "hygiene", "kinematics", "handsoff",
              "sampling"]
    print(f"vfdsl check, wall time per task (budget {BUDGET:.0f} s); in-process seconds per analysis (warm)")
    header = ["task", "cold s", "warm s", "verdict"] + stages
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for name, cold, warm, report in rows:
        timings = report["figures"].get("timings", {})
        verdict = "sound" if report["sound"] else "NOT SOUND"
        cells = [name, f"{cold:.2f}", f"{warm:.2f}", verdict] + [f"{timings.get(s, 0):.3f}" for s in stages]
        print("| " + " | ".join(cells) + " |")
    print(f"first use on a fresh machine ({tasks[0].stem}, empty cache: DAQP fetched and compiled once): {first:.2f} s")
    worst = max(max(cold, warm) for _, cold, warm, _ in rows)
    print(f"slowest: {worst:.2f} s ({'within' if worst < BUDGET else 'OVER'} the {BUDGET:.0f} s budget)")


if __name__ == "__main__":
    main()
