"""How long a long recording takes to drive `vfdsl simulate` (issue 36: "a 10-minute recording at 1 kHz replays in
under a minute").

    python benchmarks/recording_replay.py                 # 10 minutes at 1 kHz (600,000 WrenchStamped messages)
    python benchmarks/recording_replay.py --minutes 1

A bag of paper B's torque sensor is written with rosbags (tests/test_recording.py's write_bag: 1 kHz, 5 % jitter,
MCAP storage), then `vfdsl simulate tasks/paper_b_virtual_rcm.vf` runs it closed loop at the task's 10 ms period
(one trial), timed as a whole command: reading the bag, resampling, the closed loop, the metrics.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from test_recording import write_bag  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    args = parser.parse_args(argv)
    seconds = 60.0 * args.minutes
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        begin = time.perf_counter()
        write_bag(folder / "lab", seconds=seconds)
        written = time.perf_counter() - begin
        scene = folder / "run.sim.yaml"
        scene.write_text(f"duration: {seconds} s\ntrials: 1\nrecording:\n  bag: lab\n"
                         "  inputs: {tau: /ft/wrench}\n")
        begin = time.perf_counter()
        subprocess.run([sys.executable, "-m", "vfdsl.cli", "simulate", str(ROOT / "tasks" / "paper_b_virtual_rcm.vf"),
                        "--scene", str(scene), "--quiet"], check=True)
        replayed = time.perf_counter() - begin
    print(f"{args.minutes:g} min at 1 kHz ({int(seconds * 1000):,} messages): bag written in {written:.1f} s; "
          f"vfdsl simulate replayed it in {replayed:.1f} s ({seconds / replayed:.1f}x real time)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
