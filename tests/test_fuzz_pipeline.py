"""Every failure from the public API is a VfError: a few thousand mutated example files (tasks, the fixture
library, scenes) go through ``vfdsl.load`` and, when they load, through the compiler's assembly of the QP
(``vfdsl.compiler.assemble``, the step ``vfdsl.compile`` starts with; no C compile per file). Each file must
end in success or VfError, within a time limit per file, in a worker process with a memory limit.

The mutator is seeded (the same files on every run) and more hostile than the property test of
test_language_fuzz.py: besides deleting, repeating and swapping tokens it puts in extreme numbers, line
separators and control characters, deep brackets, long numbers and names, other primitives' names and
units, and repeats lines many times. The summary (files, distinct error messages, slowest file and the
worker's peak memory) is printed; run with ``-s`` to see it.
"""

from __future__ import annotations

import multiprocessing
import random
import re
import resource
import shutil
import signal
import time
import traceback
from pathlib import Path

from conftest import TASKS_DIR
from test_language_fuzz import NUMBER, SPECIAL_NUMBERS, tokens

import vfdsl
from vfdsl import VfError
from vfdsl.compiler.assemble import assemble
from vfdsl.kinematics.robot import Robot
from vfdsl.objectives import OBJECTIVES
from vfdsl.units import UNITS
from vfdsl.primitives import CONSTRAINTS

FILES = 2500
SECONDS_PER_FILE = 10
MEMORY_BYTES = 2 << 30           # address space the worker may add to what it has when it starts

SOURCES = ({p.name: p.name for p in sorted(TASKS_DIR.glob("*.vf"))}
           | {"library/fixtures.vf": "paper_b_virtual_rcm.vf"}
           | {p.name: p.with_suffix(".vf").name for p in sorted(TASKS_DIR.glob("*.yaml"))})
WORDS = sorted(CONSTRAINTS) + sorted(OBJECTIVES) + sorted(UNITS) + ["pose", "curve", "in", "soft", "within"]
ODD_TEXT = ["\u2028", "\x85", "\f", "\t", "\x00", "\x1b[2J", "\u00b5m", "+", "-", "*", "/", "&a", "*a", "{", "}",
            "[" * 40, "]", "(", ")", "1" * 60, "x" * 200, "1e308", "nan", "inf", "\"", "#", ":", "\n"]


def mutate(text: str, rng: random.Random) -> str:
    """One to three random edits of ``text``."""
    for _ in range(rng.randint(1, 3)):
        toks = tokens(text)
        significant = [i for i, t in enumerate(toks) if not t.isspace()] or [0]
        i = rng.choice(significant)
        op = rng.randrange(8)
        if op == 0:
            del toks[i]
        elif op == 1:
            toks.insert(i, toks[i] + " ")
        elif op == 2:
            j = rng.choice(significant)
            toks[i], toks[j] = toks[j], toks[i]
        elif op == 3:
            numbers = [k for k, t in enumerate(toks) if NUMBER.fullmatch(t)] or [i]
            toks[rng.choice(numbers)] = rng.choice(SPECIAL_NUMBERS + ["0.0000001", "-1e-12", "89.999", "90"])
        elif op == 4:
            names = [k for k, t in enumerate(toks) if t[:1].isalpha()] or [i]
            toks[rng.choice(names)] = rng.choice(WORDS)
        elif op == 5:
            toks.insert(i, rng.choice(ODD_TEXT))
        elif op == 6:
            lines = "".join(toks).splitlines(keepends=True) or [""]
            k = rng.randrange(len(lines))
            lines[k:k + 1] = [lines[k]] * rng.choice([2, 50, 600])
            toks = ["".join(lines)]
        else:
            toks.insert(i, chr(rng.randrange(1, 0x3000)))
        text = "".join(toks)
    return text


def error_code(err: VfError) -> str:
    """The message with names, numbers and paths taken out: one code per kind of error."""
    code = re.sub(r"'[^']*'|\"[^\"]*\"|`[^`]*`|/\S+", "_", err.message)
    return re.sub(r"[-+]?\d[\d.,eE+-]*", "N", code)


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout()


def _worker(workdir: Path, seed: int, count: int, queue) -> None:
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    current = int(open("/proc/self/status").read().split("VmSize:")[1].split()[0]) * 1024
    limit = current + MEMORY_BYTES if hard == resource.RLIM_INFINITY else min(hard, current + MEMORY_BYTES)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    signal.signal(signal.SIGALRM, _alarm)
    rng = random.Random(seed)
    robots: dict[str, Robot] = {}
    codes: dict[str, int] = {}
    failures, loaded, slowest = [], 0, (0.0, "", 0)
    for _ in range(count):
        source = rng.choice(sorted(SOURCES))
        original = (TASKS_DIR / source).read_text()
        text = mutate(original, rng)
        (workdir / source).write_text(text, encoding="utf-8", errors="surrogatepass")
        rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        start = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, SECONDS_PER_FILE)
        try:
            task = vfdsl.load(workdir / SOURCES[source])
            urdf = task.robots[0].urdf
            robots.setdefault(urdf, Robot.load(urdf))
            assemble(task, robots[urdf])
            loaded += 1
        except VfError as err:
            err.render()
            code = error_code(err)
            codes[code] = codes.get(code, 0) + 1
        except _Timeout:
            failures.append((source, text, f"took more than {SECONDS_PER_FILE} s"))
        except BaseException as exc:  # noqa: BLE001 - the point of the test
            failures.append((source, text, "".join(traceback.format_exception(exc, limit=-6))))
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            (workdir / source).write_text(original)
        seconds = time.perf_counter() - start
        if seconds > slowest[0]:
            grown = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss_before
            slowest = (seconds, f"{source}: {text[:300]!r}", grown)
    queue.put({"loaded": loaded, "codes": codes, "failures": failures[:5], "n_failures": len(failures),
               "slowest": slowest, "peak_rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss})


def test_mutated_files_load_and_assemble_or_raise_vferror(tmp_path):
    workdir = tmp_path / "tasks"
    shutil.copytree(TASKS_DIR, workdir)
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    worker = context.Process(target=_worker, args=(workdir, 11, FILES, queue))
    worker.start()
    result = queue.get(timeout=FILES * SECONDS_PER_FILE)
    worker.join(timeout=60)
    assert result["n_failures"] == 0, "\n\n".join(f"{s}: {t!r}\n{why}" for s, t, why in result["failures"])
    errors = sum(result["codes"].values())
    seconds, slowest_file, grown_kb = result["slowest"]
    print(f"\n{FILES} mutated files: {result['loaded']} loaded and assembled, {errors} VfError with "
          f"{len(result['codes'])} distinct messages; slowest file {seconds:.2f} s (peak RSS grew "
          f"{grown_kb / 1024:.1f} MB during it): {slowest_file}; worker peak RSS {result['peak_rss_kb'] / 1024:.0f} MB")
    assert result["loaded"] + errors == FILES
    assert result["loaded"] >= FILES // 20 and errors >= FILES // 2      # the mutator both keeps and breaks files
    assert len(result["codes"]) >= 40
