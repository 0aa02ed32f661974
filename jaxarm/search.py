"""``solve``: many independent PSO restarts of one problem, and the ``Result`` they produce."""

from __future__ import annotations

import json
import math
import numbers
import pathlib
import time
from typing import Callable, NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxarm._validate import check_search, positive_int
from jaxarm.checks.evaluate import certify, deepest_contact
from jaxarm.choices import (DEFAULT_CONSTRAINT, DEFAULT_METHODS, DEFAULT_RESTARTS,
                            DEFAULT_TIME_LIMIT, MAX_DEGREE)
from jaxarm.escalation import Stage, escalate
from jaxarm.io.files import text_writer, write_or_return
from jaxarm.model.problem import Problem, check_problem
from jaxarm.optim import evosax_adapter, pso
from jaxarm.optim.custom import CustomConfig, RecordedOptimizer
from jaxarm.optim.methods import parse_method, swarm_size
from jaxarm.optim.restarts import N_ITERS, N_PARTICLES, RestartOutcome


def exact_text(x) -> str:
    """Free parameters as ``[a, b, ...]`` with the shortest digits that give back the same
    float32 values: a printed optimum, which sits on an obstacle's edge, pasted back into
    ``fitness`` is the same path (4 rounded decimals can make it collide)."""
    values = np.asarray(x, dtype=np.float32).ravel()
    return "[" + ", ".join(np.format_float_positional(v, unique=True, trim="-")
                           for v in values) + "]"


def coefficient_label(degree: int) -> str:
    """What the free parameters x of a degree are, as the summary labels them: the paper's
    ``a6`` (a6 of every joint) at degree 6, ``a6..a8`` (by power, then joint) at degree 8."""
    return "a6" if degree == 6 else f"a6..a{degree}"


def _nothing_escaped(result: Result, flags: bool, obstacle_names: dict | None) -> str:
    """The summary's line when no restart found a collision-free path: what ran, where the
    best path collides, and what to try, in the words of the interface in use (``flags``: the
    command line's; else Python's keywords), never a degree already tried. ``obstacle_names``
    renames ``World``'s names (``"boxes[0]"``) as a scenario file gives them."""
    restarts = "--restarts N" if flags else "n_restarts=N"
    tries = [f"more restarts ({restarts})"]
    if result.constraint != "feasibility":  # named with the method, which takes any rule
        named = result.method != "custom"
        if flags:
            tries.append(f"feasibility rules (--method {result.method}:feasibility)" if named
                         else "feasibility rules (--constraint feasibility)")
        else:
            tries.append(f'feasibility rules (method "{result.method}:feasibility")' if named
                         else 'feasibility rules (constraint="feasibility")')
    degrees = sorted({stage.degree for stage in result.stages} | {result.degree})
    if result.time_limit is not None and result.stages and result.stages[-1].time_ran_out:
        longer = f"{2 * result.time_limit:g}"
        tries.insert(0, f"a longer time limit (--time-limit {longer})" if flags
                     else f"a longer time limit (time_limit={longer})")
    higher = min(degrees[-1] + 2, MAX_DEGREE)
    if higher > degrees[-1]:
        tries.append(f"a higher degree (--degree {higher})" if flags
                     else f"a higher degree (problem.replace(degree={higher}))")
    ran = (f"{result.n_restarts} restart(s) of {result.method} under {result.constraint} rules "
           f"(degree {result.degree})") if len(result.stages) <= 1 else (
        f"{sum(stage.n_restarts for stage in result.stages)} restart(s) in "
        f"{len(result.stages)} stages of {result.method} under {result.constraint} rules "
        f"(degrees {', '.join(map(str, degrees))})")
    return (f"HINT     none of {ran} found a collision-free path: "
            f"try {', '.join(tries[:-1]) + ' or ' + tries[-1] if len(tries) > 1 else tries[0]}; "
            f"the best path found is not free, violation "
            f"{float(result.restarts.best_violation[result.best_restart]):.3g} (cm deep at its "
            f"deepest sample, plus rad outside a joint's limits)"
            + _where_it_collides(result.witness, obstacle_names))


def _where_it_collides(witness, obstacle_names: dict | None) -> str:
    """``Result.witness`` in words (empty without one)."""
    if witness is None:
        return ""
    return f"; its deepest contact: {_contact_words(witness, obstacle_names)}"


def _contact_words(witness: tuple, obstacle_names: dict | None) -> str:
    """A ``Result.witness`` as "link 2 is 0.3 cm inside circles[0] at r = 0.41"."""
    r, link, _, distance, name = witness
    name = (obstacle_names or {}).get(name, name)
    how = (f"{-distance:.3g} cm inside {name}" if distance < 0
           else f"{distance:.3g} cm from {name}, inside the margin")
    return f"link {link + 1} is {how} at r = {r:.4g}"


def _stages_line(result: Result) -> list[str]:
    """The stages an escalating search ran, when there was more than one."""
    if len(result.stages) <= 1:
        return []
    limit = "" if result.time_limit is None else f" (time limit {result.time_limit:g} s)"
    parts = [f"degree {stage.degree} x {stage.n_restarts}{' seeded' if stage.seeded else ''}"
             for stage in result.stages]
    return [f"stages   {len(result.stages)} in {result.stages[-1].seconds:.1f} s{limit}: "
            + ", ".join(parts)]


WITNESS_KEYS = ("r", "link", "obstacle", "distance", "name")  # ``Result.witness``'s fields


class Result(NamedTuple):
    """What ``solve`` found: every restart, the best one, and how it was produced.

    The best restart's fields are properties (``best_x``, ``best_fitness``, ``feasible``,
    ``escape_iter``, ``history``); ``restarts`` holds every restart's outcome.
    """

    restarts: RestartOutcome  # NumPy arrays with leading axis n_restarts
    best_restart: int  # index of the best restart (``RestartOutcome.best_restart``)
    certified: bool  # best_x proved free for every r by ``jaxarm.certify``
    pso_best_fitness: float  # best_fitness before refinement (equal when refine=False)
    method: str  # the method's name without its rule ("A", "A-ring", "evosax:CMA_ES"),
    #   "custom", a user's optimiser's label, or the default search's
    #   "A-ring[inertia_end=0.4] x 8 + A x 8"
    config: (pso.PSOConfig | evosax_adapter.StrategyConfig | CustomConfig
             | RecordedOptimizer)  # the best restart's method's (a saved record's user
    #   optimiser: its label alone)
    constraint: str
    collision: str  # the collision mode the search used
    degree: int  # the degree of the paths in ``restarts`` (the problem's, or the one an
    #   escalating search found its best path at)
    seed: int
    seconds: float  # wall time of the call, compilation included
    stages: tuple = ()  # ``escalation.Stage`` per stage run (none in records made before them)
    time_limit: float | None = None  # s, the search's (None: none)
    witness: tuple | None = None  # where the best path collides, when it does: (r, link
    #   (0-based), obstacle (index in ``World``'s order), distance (cm), the obstacle's name
    #   in ``World``: "boxes[2]") (``evaluate.deepest_contact``); for a path free only at
    #   the sampled check's samples, where ``certify`` finds it colliding between them

    @property
    def best_x(self) -> np.ndarray:
        """Shape (n_free,), the best restart's global best."""
        return self.restarts.best_x[self.best_restart]

    @property
    def best_fitness(self) -> float:
        """Paper eq. 17 fitness of best_x (0 if infeasible)."""
        return float(self.restarts.best_fitness[self.best_restart])

    @property
    def feasible(self) -> bool:
        """best_x is collision-free in the problem's collision mode."""
        return bool(self.restarts.feasible[self.best_restart])

    @property
    def escape_iter(self) -> int:
        """The best restart's escape iteration, -1 if it never escaped."""
        return int(self.restarts.escape_iter[self.best_restart])

    @property
    def history(self) -> np.ndarray:
        """Shape (n_iters + 1,), the best restart's global-best fitness per iteration."""
        return self.restarts.history[self.best_restart]

    @property
    def n_restarts(self) -> int:
        return int(self.restarts.best_fitness.shape[0])

    def summary(self, flags: bool = False, obstacle_names: dict | None = None) -> str:
        """A few human-readable lines; ``flags``: a hint names the command line's flags
        (``jaxarm solve``) instead of Python's keywords; ``obstacle_names``: ``World``'s
        obstacle names (``"boxes[0]"``) -> the names to print (a scenario file's)."""
        escaped = int(np.sum(self.restarts.escape_iter >= 0))
        return "\n".join([
            f"method {self.method} ({self.config.velocity_rule}), constraint {self.constraint}, "
            f"{self.n_restarts} restart(s), degree {self.degree}, {self.collision} collision "
            f"check, seed {self.seed}",
            *_stages_line(self),
            f"{f'best {coefficient_label(self.degree)}':<8} {exact_text(self.best_x)}",
            f"fitness  {self.best_fitness:.5g}  feasible {self.feasible}  "
            f"certified {self.certified}",
            *([f"WARNING  feasible only at the {self.collision} check's samples: "
               + (f"between them, {_contact_words(self.witness, obstacle_names)} "
                  "(jaxarm.certify)" if self.witness is not None else
                  "the motion is not certified collision-free between them")]
              if self.feasible and not self.certified else []),
            f"escape   iteration {self.escape_iter} (best restart); "
            f"{escaped}/{self.n_restarts} restarts escaped",
            *([_nothing_escaped(self, flags, obstacle_names)] if not self.feasible else []),
            f"time     {self.seconds:.2f} s",
        ])

    def to_dict(self) -> dict:
        """Plain lists and numbers, NaN as None (strict JSON); ``Result.from_dict`` reads it back.

        Besides the fields, it carries the best restart's ``best_x``, ``best_fitness``,
        ``feasible``, ``escape_iter`` and ``history`` for readers who only want the answer.
        """
        return {
            "best_x": self.best_x.tolist(),
            "best_fitness": self.best_fitness,
            "feasible": self.feasible,
            "escape_iter": self.escape_iter,
            "history": self.history.tolist(),
            "restarts": {name: _plain(a) for name, a in self.restarts._asdict().items()},
            "best_restart": self.best_restart,
            "certified": self.certified,
            "pso_best_fitness": self.pso_best_fitness,
            "method": self.method,
            "config": self.config._asdict(),
            "constraint": self.constraint,
            "collision": self.collision,
            "degree": self.degree,
            "seed": self.seed,
            "seconds": self.seconds,
            "stages": [{key: None if isinstance(value, float) and math.isinf(value) else value
                        for key, value in stage._asdict().items()} for stage in self.stages],
            "time_limit": self.time_limit,
            "witness": None if self.witness is None else dict(
                zip(WITNESS_KEYS, self.witness)),
        }

    @classmethod
    def from_dict(cls, data: dict) -> Result:
        """The ``Result`` that ``to_dict`` wrote (arrays as float64 / int32, NaN kept)."""
        integer = {"escape_iter"}
        restarts = RestartOutcome(**{
            name: np.asarray(values, dtype=np.int32 if name in integer else np.float64)
            for name, values in data["restarts"].items()})
        # (records written before ``degree``, ``stages``, ... were kept have none)
        optional = {"degree", "stages", "time_limit", "witness"}
        fields = {name: data.get(name) if name in optional else data[name]
                  for name in cls._fields if name != "restarts"}
        fields["stages"] = tuple(  # to_dict wrote infinities as None
            Stage(**{key: math.inf if value is None else value for key, value in stage.items()})
            for stage in fields["stages"] or ())
        if fields["witness"] is not None:
            fields["witness"] = tuple(fields["witness"][key] for key in WITNESS_KEYS)
        config = fields["config"]
        fields["config"] = (evosax_adapter.StrategyConfig(**config) if "strategy" in config
                            else RecordedOptimizer(**config) if "optimizer" in config
                            else pso.PSOConfig(**config))
        return cls(restarts=restarts, **fields)

    def to_json(self, path_or_file=None) -> str | pathlib.Path:
        """``to_dict()`` as strict JSON: the text, or written to ``path_or_file`` (a path,
        written whole, or an open text file; then that is returned)."""
        return write_or_return(path_or_file,
                               text_writer(json.dumps(self.to_dict(), allow_nan=False)))

    @classmethod
    def from_json(cls, text: str) -> Result:
        """The ``Result`` in JSON text: ``to_json``'s, or the ``result`` of a ``solve --json``
        record (``load_run`` gives that record's problem and settings too)."""
        data = json.loads(text)
        return cls.from_dict(data["result"] if "settings" in data else data)


def _plain(array) -> list:
    """Nested lists of Python numbers, NaN as None."""
    array = np.asarray(array)
    if array.dtype.kind == "f":
        return np.where(np.isnan(array), None, array).tolist()
    return array.tolist()


def solve(problem: Problem, method=None, *, n_particles: int | None = None,
          n_iters: int = N_ITERS, n_restarts: int | None = None, seed: int = 0,
          constraint: str | None = None, init_particles=None, refine: bool | str = False,
          time_limit: float | None = None, max_stages: int | None = None,
          improve: bool = False, progress: Callable | bool | None = None) -> Result:
    """Search the problem's free coefficients with PSO, ``n_restarts`` independent swarms at once,
    and, under a time limit, more restarts and higher degrees until a path is proved free.

    With no method, ``DEFAULT_RESTARTS`` (8) swarms of each of ``DEFAULT_METHODS`` (preset A
    with the ring topology and inertia falling to 0.4, then preset A) under
    ``DEFAULT_CONSTRAINT`` (feasibility rules), and the best of them: the search meant to find
    a collision-free path (``jaxarm.choices`` says why these). It is anytime: when no
    restart's path is certified free, it goes on for up to ``DEFAULT_TIME_LIMIT`` seconds
    (120) with more restarts, then higher degrees seeded with the best paths so far
    (``jaxarm.escalation``), and returns the best certified path at the degree it was found
    (``Result.degree``; ``Result.stages`` says what ran). It stops at the first stage that
    certifies a path, or with ``improve=True`` spends the rest of the time on the next stages
    and keeps the fittest. Naming a method runs that method, and by default one swarm, once, as
    the paper did: ``solve(problem, "A")`` is the paper's preset A with its death penalty; give
    it a ``time_limit`` to escalate it the same way.

    Restart i is seeded by ``fold_in(key(seed), i)``; its result does not depend on
    ``n_restarts`` (see ``jaxarm.optim.restarts``). The stages come in a fixed order, so the
    time limit decides only how many run; ``max_stages`` repeats a run stage for stage.

    Args:
      problem: the problem.
      method: a method name (``jaxarm.optim.methods``): "A", "B", "C" (the paper's Table 2
        presets), "A-ring", "A-ring[inertia_end=0.4]" (fields changed in brackets), an
        evosax strategy "evosax:CMA_ES" (optional dependency), each optionally followed by
        ":<constraint>" ("A:feasibility"); or a ``PSOConfig``; or your own optimiser
        (``jaxarm.optim.custom``: an object with ``label``, ``population``, ``init``, ``ask``,
        ``tell``); None: the default above.
      n_particles: swarm size (paper: 20); None: your optimiser's population, else 20.
      n_iters: PSO updates (paper: 100); iteration 0 is the initial swarm.
      n_restarts: independent swarms (default: 8 per default method, 1 with a named one).
        Restarts are numbered across the default's methods: the first method's are 0 ..
        n - 1, the next's n .. 2n - 1; later stages take the numbers after them.
      seed: integer seed in [0, 2**31).
      constraint: "death" (paper eq. 17), "feasibility" (feasibility rules), "epsilon" or
        "penalty" (``jaxarm.optim.constraints``); default: the rule ``method`` names, else
        "death" (feasibility rules with the default method). ``solve(p, "A:feasibility")``
        is ``solve(p, "A", constraint="feasibility")``; a method that names another rule
        than ``constraint`` is a ValueError.
      init_particles: optional particles, shape (n_given, n_free), put at the start of every
        restart's initial swarm (paper Table 6).
      refine: polish with ``jaxarm.refine`` after PSO: False, True (the best restart) or
        "all" (every feasible restart, then the best is chosen again). Never worse.
      time_limit: seconds (compilation included) the search may go on while nothing is
        certified free; None: none when ``max_stages`` is given, else ``DEFAULT_TIME_LIMIT``
        with the default method and no escalation with a named one; ``math.inf``: the whole
        plan. Stage 0 (the call as asked) always runs whole; a later stage only when it is
        expected to end within the limit.
      max_stages: run at most this many stages (None: as many as the time allows); 1 is the
        call as asked, without escalation.
      improve: go on after a certified path is found, until the time or the plan runs out,
        keeping the fittest certified path.
      progress: called with each finished ``escalation.Stage`` (its ``line()`` is one line of
        text); None: logged by the ``jaxarm.search`` logger at INFO; False: silent.

    Returns:
      ``Result``.

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> result = jaxarm.solve(problem, "A:feasibility", n_particles=6, n_iters=5)
      >>> result.feasible, result.certified, result.best_x.shape
      (True, True, (3,))
    """
    began = time.perf_counter()
    variants, n_restarts = _variants(method, constraint, n_restarts, init_particles)
    constraint = variants[0].constraint
    n_particles = swarm_size(variants, n_particles, N_PARTICLES)
    check_search(n_particles=n_particles, n_iters=n_iters, seed=seed, constraint=constraint,
                 restarts_at_once=n_restarts)
    if refine not in (False, True, "all"):
        raise ValueError(f"refine must be False, True or 'all', got {refine!r}")
    limit, max_stages = _stage_limits(method, time_limit, max_stages, improve, progress)
    given = _check_init_particles(check_problem(problem), init_particles, n_particles)
    found = escalate(problem, variants, constraint, n_particles=n_particles, n_iters=n_iters,
                     n_restarts=n_restarts, seed=seed, init_particles=given, time_limit=limit,
                     max_stages=max_stages, improve=improve, progress=progress, began=began)
    problem, outcome = found.problem, found.outcome
    pso_best = float(outcome.best_fitness[outcome.best_restart()])
    if refine:
        outcome = _refined(problem, outcome, every=refine == "all")
    best = _best(problem, outcome, found.certified, refine)
    certified, witness = _verdict(problem, outcome.best_x[best], bool(outcome.feasible[best]))
    method_name = (variants[0].name if len(variants) == 1 else
                   " + ".join(f"{variant.name} x {count}"
                              for variant, count in zip(variants, found.n_restarts)))
    return Result(restarts=outcome, best_restart=best, certified=certified,
                  pso_best_fitness=pso_best, method=method_name,
                  config=variants[int(found.variant[best])].config,
                  constraint=constraint, collision=problem.collision, degree=problem.degree,
                  seed=int(seed), seconds=time.perf_counter() - began, stages=found.stages,
                  time_limit=None if math.isinf(limit) else limit, witness=witness)


def _best(problem: Problem, outcome: RestartOutcome, certified, refined) -> int:
    """The restart ``solve`` returns: the best (``best_restart``), except under the sampled
    check where a path is known certified (and not refined since): the fittest such, rather
    than a fitter one only the samples call free."""
    if problem.collision == "sampled" and certified.any() and not refined:
        return int(np.argmax(np.where(certified, outcome.best_fitness, -np.inf)))
    return outcome.best_restart()


def _variants(method, constraint, n_restarts, init_particles) -> tuple[list, int]:
    """The methods ``solve`` runs (``Variant``s) and the restarts of each, checked."""
    if method is None:
        constraint = DEFAULT_CONSTRAINT if constraint is None else constraint
        variants = [parse_method(name, constraint) for name in DEFAULT_METHODS]
        n_restarts = DEFAULT_RESTARTS if n_restarts is None else n_restarts
    else:
        variants = [parse_method(method, constraint)]
        n_restarts = 1 if n_restarts is None else n_restarts
    if (isinstance(variants[0].config, (evosax_adapter.StrategyConfig, CustomConfig))
            and init_particles is not None):
        raise ValueError(f"init_particles: {variants[0].name} starts from its own "
                         "population; give init_particles to a PSO method")
    return variants, positive_int("n_restarts", n_restarts)


def _stage_limits(method, time_limit, max_stages, improve, progress) -> tuple[float, int | None]:
    """``solve``'s time limit (s; inf: none) and stage count, checked."""
    if time_limit is None:  # max_stages bounds the work; else the default's limit, or one stage
        time_limit = DEFAULT_TIME_LIMIT if method is None and max_stages is None else math.inf
        if method is not None and max_stages is None:
            max_stages = 1
    elif isinstance(time_limit, bool) or not isinstance(time_limit, numbers.Real) or not (
            time_limit > 0):
        raise ValueError(f"time_limit must be a positive number of seconds, got {time_limit!r}")
    if max_stages is not None:
        max_stages = positive_int("max_stages", max_stages)
    if not isinstance(improve, bool):
        raise ValueError(f"improve must be True or False, got {improve!r}")
    if improve and max_stages == 1:
        raise ValueError("improve=True needs more than one stage: give a named method a "
                         "time_limit, or max_stages > 1")
    if not (progress is None or progress is False or callable(progress)):
        raise ValueError(f"progress must be a function, None or False, got {progress!r}")
    return float(time_limit), max_stages


def _witness(problem: Problem, x) -> tuple | None:
    """``Result.witness`` of the path x (``evaluate.deepest_contact``), or None where there is
    no contact (a joint limit alone)."""
    found = deepest_contact(problem, x)
    if not found.found:
        return None
    name = (problem.world.obstacle_name(int(found.obstacle)) if found.obstacle >= 0
            else f"link {int(found.other_link) + 1}")
    return float(found.r), int(found.link), int(found.obstacle), float(found.distance), name


def _verdict(problem: Problem, x, feasible: bool) -> tuple[bool, tuple | None]:
    """``Result.certified`` and ``Result.witness`` of the best path x, which the search's
    check called ``feasible``: a path free at the sampled check's samples alone is certified
    here (and its witness is where ``certify`` finds it colliding, if it does)."""
    if not feasible:
        return False, _witness(problem, x)
    if problem.collision == "certified":
        return True, None
    certificate = certify(problem, x)
    return bool(certificate.free), _certified_witness(problem, certificate)


def _certified_witness(problem: Problem, certificate) -> tuple | None:
    """``Result.witness`` of a path the sampled check calls free, where ``certify``'s
    ``certificate`` finds it colliding between the samples; None otherwise (proved free, or
    undecided)."""
    if not bool(certificate.colliding):
        return None
    obstacle, other = int(certificate.witness_obstacle), int(certificate.witness_other_link)
    if obstacle < 0 and other < 0:  # a joint limit alone
        return None
    name = problem.world.obstacle_name(obstacle) if obstacle >= 0 else f"link {other + 1}"
    return (float(certificate.witness_r), int(certificate.witness_link), obstacle,
            float(certificate.clearance), name)


def _refined(problem, outcome: RestartOutcome, every: bool) -> RestartOutcome:
    """The outcome with the best (or every) feasible restart polished by ``refine``."""
    from jaxarm.optim.refine import refine

    rows = np.arange(len(outcome.best_fitness)) if every else np.array([outcome.best_restart()])
    rows = rows[outcome.feasible[rows]]
    if rows.size == 0:
        return outcome
    polished = refine(problem, outcome.best_x[rows])
    # Kept only where strictly fitter than the PSO's own evaluation: the same x evaluated by
    # another compiled program can differ in the last bit, and "never worse" must hold here.
    better = polished.fitness > outcome.best_fitness[rows]
    best_x, best_fitness = outcome.best_x.copy(), outcome.best_fitness.copy()
    best_x[rows[better]], best_fitness[rows[better]] = polished.x[better], polished.fitness[better]
    return outcome._replace(best_x=best_x, best_fitness=best_fitness)


def _check_init_particles(problem, init_particles, n_particles):
    if init_particles is None:
        return None
    given = np.asarray(init_particles, dtype=np.float64)
    if given.ndim == 1:
        given = given[None]
    if given.ndim != 2 or given.shape[1] != problem.n_free or given.shape[0] > n_particles:
        raise ValueError(
            f"init_particles must have shape (n_given <= {n_particles}, {problem.n_free}), "
            f"got {np.shape(init_particles)}"
        )
    if not np.all(np.isfinite(given)):
        raise ValueError(f"init_particles must be finite, got {init_particles!r}")
    return given.astype(jnp.result_type(float))
