"""The names (and path degrees) the library accepts, kept free of JAX so the CLI can offer and
check them without loading it.

``pso.PRESETS``, ``constraints.constraint_index`` and ``Problem`` check their arguments against
these tuples; ``jaxarm.cli`` builds its ``choices=`` from them.
"""

import re

VELOCITY_RULES = ("original", "inertia", "constriction")
TIE_BREAKS = ("first", "random")
BETA_MODES = ("dimension", "particle")
TOPOLOGIES = ("global", "ring", "global-ring")  # see jaxarm.optim.pso
CONSTRAINTS = ("death", "feasibility", "epsilon", "penalty")  # see jaxarm.optim.constraints
COLLISION_MODES = ("sampled", "certified")
CLUTTER_KINDS = ("circles", "triangles", "boxes")  # see jaxarm.model.clutter
MIN_DEGREE = 6  # the paper's: a0..a5 meet the six rest-to-rest end conditions
# The highest path degree. float32 paths and distances and Simpson's rule at 101 samples stay
# accurate well past it; the certified check, the default, is what binds: the memory and time
# to compile its search grow with the degree (its Taylor expansions have (degree + 1)^2 terms
# per joint), and 24 keeps it within a laptop's memory (``benchmarks/degree_limit.py``;
# ``benchmarks/RESULTS.md``, *Path degree limit*).
MAX_DEGREE = 24
# ``trajectory.min_duration``'s limits (keywords ``max_<name>``, CLI ``--max-<name>``), with units
LIMIT_UNITS = {"velocity": "rad/s", "acceleration": "rad/s^2", "jerk": "rad/s^3",
               "torque": "N m"}
PRESET_NAMES = ("A", "B", "C")  # the paper's Table 2
# "A-ring": preset A with the ring topology; "A-global-ring": with "global-ring" (``jaxarm.optim.methods``)
TOPOLOGY_SUFFIXES = {"-ring": "ring", "-global-ring": "global-ring"}
PSO_METHODS = PRESET_NAMES + tuple(name + suffix for suffix in TOPOLOGY_SUFFIXES
                                   for name in PRESET_NAMES)
# What ``solve`` and ``jaxarm solve`` run when no method is named: restarts of each of these
# methods under feasibility rules, the best of them kept. The ring with its slower inertia
# escapes where the global best often does not (death-trap); the global best converges closer
# to the optimum where both escape (five-link-detour). Measured on every shipped scene by
# ``benchmarks/default_bench.py``. The paper's settings are one name away: method "A" is its
# preset A with the death penalty, one swarm.
DEFAULT_METHODS = ("A-ring[inertia_end=0.4]", "A")
DEFAULT_CONSTRAINT = "feasibility"
DEFAULT_RESTARTS = 8  # per method
# Seconds the default search goes on while nothing is certified free (``jaxarm.escalation``):
# on 2 CPU cores, compiling included, time for the seeded higher degrees that find the paths
# degree 6 misses, and short enough to wait for at a terminal.
DEFAULT_TIME_LIMIT = 120.0
# What one compiled search call holds: restarts x particles paths evaluated together (each with
# its check's working arrays), and restarts x (iterations + 1) float32 values of history. The
# bounds are at least twice what benchmarks/escape_bench.py runs at once on a GPU (100,000
# restarts x 20 particles) and stop a size such as 10**9 before it allocates what no machine
# holds.
MAX_PATHS_AT_ONCE = 2**22
MAX_HISTORY_AT_ONCE = 2**26
MAX_SAMPLES = 100_001  # points of r: 1000 times the paper's 101


def split_methods(text: str) -> list[str]:
    """``"A,A-ring[inertia_end=0.4,social_coeff=2]:feasibility"`` as its methods, stripped: a
    comma inside brackets belongs to its method (``jaxarm.optim.methods``)."""
    return [method.strip() for method in re.split(r",(?![^\[]*\])", text)]


def one_of(field: str, value, options: tuple) -> str:
    """``value`` if it is one of ``options``, else a ValueError naming ``field`` and the value."""
    if value not in options:
        raise ValueError(f"{field} must be one of {options}, got {value!r}")
    return value
