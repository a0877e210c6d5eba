"""Resource limits the front end enforces before any work starts.

Resource limits sit far above any real task (about ten times the largest example, or more where a real
task could grow, such as a digitized curve), so that a hostile or mistaken file fails fast with a message
that names the limit instead of taking the machine's time or memory. They are listed in docs/language.md
("Limits"); :func:`exceeded` builds the error.
"""

from __future__ import annotations

from vfdsl.errors import Span, VfError

FILE_BYTES = 1_000_000           # a task, library, scene or sidecar file
IMPORT_DEPTH = 16                # libraries importing libraries
IMPORTED_FILES = 256             # files in one program
NESTING = 16                     # brackets and calls inside one value: [[[...]]], f(g(...))
NUMBER_CHARS = 40                # characters of one number literal
NAME_CHARS = 100                 # characters of one name
FIXTURE_DEPTH = 16               # `use` inside a fixture inside a fixture ...
EXPANDED_STATEMENTS = 2_000      # statements after expanding every fixture
CONSTRAINTS = 1_000              # `require` statements after expansion
ROWS = 8_192                     # constraint rows (an upper estimate from the resolutions), joint bounds excluded
RESOLUTION = 64                  # directions per angle of a polytope (64 x 64 at most for a sphere)
PRIORITY_LEVELS = 5                 # `priority` 1..5: each level is one more QP solve per tick
CURVE_DEGREE = 9
CURVE_POINTS = 128
CURVE_SAMPLES = 2_048            # closest-point samples of one curve (about 2 m of curve at 1 mm)
YAML_NODES = 100_000             # nodes of a scene after alias expansion
YAML_DEPTH = 16                  # nesting of lists and mappings in a scene
LENGTH = 1_000.0                 # m: a task frame's distance from its link (its offset, composed)
MESH_TRIANGLES = 100_000         # triangles of one mesh: its query's tables are C arrays, compiled with each task
                                 # (3 min at this size on a loaded 2-core machine, 6 min at 200,000; docs/language.md)
MESH_FILE_BYTES = 500 * MESH_TRIANGLES   # bytes of one mesh file, refused unparsed: above, it holds more triangles
                                 # in any format (an ASCII STL facet, the most verbose, ~290 at full precision)

# Work a command may be asked to do (`vfdsl simulate`, `vfdsl check`, `vfdsl view`): a mistaken option or scene value
# must not fill the memory or run for days before anything is printed.
PROCEDURE_DURATION = 3600.0       # s: the longest `for` and `blend` (an hour; a longer one is a unit slip)
MIN_PERIOD = 1e-5                # s: the shortest control period (100 kHz)
MAX_PERIOD = 1.0                 # s: the longest control period: a longer tick lets the speed bounds allow large jumps
TRIAL_TICKS = 1_000_000          # control ticks of one trial (duration / period; 10,000 s at 10 ms)
RUN_TICKS = 20_000_000           # control ticks of one `simulate` run, all trials and grid points
TRIALS = 100_000                 # trials per setting
GRID_POINTS = 1_000              # settings of one sweep (the product of every --grid)
ROW_VALUE = 1e6                  # m, rad, m/s or rad/s: the largest length, speed or length tolerance a task may
                                 # state (the loader refuses more: a unit slip), and the largest number in a
                                 # constraint's rows `check` analyses (LPs)
GAIN = 1e6                       # SI: the largest gain of `track` (m/s per N, rad/s per N m, or a twist's scale);
                                 # 1 / GAIN the smallest
TELEOP_SCALE = 100.0             # the largest `teleop` scale (tool motion per master motion): surgical masters scale
                                 # down (0.2-1); at 100 a 0.1 mm tremor of the hand moves the tool 10 mm, and more is
                                 # a ratio written upside down (1:500 as 500 instead of 0.002)
HAPTIC_FORCE = 1_000.0           # N: the largest force `teleop` may feed back (its `saturation`): hand-held masters
                                 # give 3-40 N; more pushes the operator's hand harder than any master can
CHECK_SAMPLES = 5_000            # states of check's random walk (about 7 ms each on a loaded 2-core machine)
SEED = 2 ** 32 - 1               # the largest seed (seeds are 0 or more)
CONNECT_TIMEOUT = 10.0           # s: to reach a Dask scheduler and hear its handshake
TRACE_BYTES = 1_000_000_000      # a trace `view --replay` plays (about 1.6 million ticks of a simulate trace)
PICTURE_SIDE = 8_192             # pixels: the width or height of a `view --screenshot`

def exceeded(what: str, limit: int | float, pos: Span | None, hint: str | None = None,
             unit: str = "", code: str | None = None) -> VfError:
    """The error for a resource limit: which one was hit, and its value (``code``: E701 in a task's files)."""
    value = f"{limit:,}" if isinstance(limit, int) else f"{limit:g}"
    return VfError(f"{what}: the limit is {value}{' ' + unit if unit else ''}", pos,
                   hint=hint or "this limit sits far above any real task; split the task or simplify it", code=code)
