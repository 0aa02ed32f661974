"""Your own optimiser as a method of ``solve`` and ``escape_study``.

Any object with these five members is a method, beside the PSO presets and evosax's strategies:

    label = "(1+8)-ES"          # its name in tables, CSV and JSON
    population = 8              # paths asked per iteration
    init(key, low, high)        # -> state (a pytree); low, high: the init range, (n_free,)
    ask(key, state)             # -> (x, state); x: (population, n_free)
    tell(state, x, evaluation)  # -> state; evaluation: ``jaxarm.Evaluation`` of x

jaxarm runs it as it runs the PSO (``jaxarm.optim.restarts``): its functions see one restart,
vmapped over restarts and scanned over iterations in one compiled program, restart i seeded by
``fold_in(key(seed), i)``. Iteration 0 is ``init`` then ``ask`` (with the two halves of the
iteration's key), told its evaluation; iteration t >= 1 asks with that iteration's key and
tells. The evaluation is the search's own measurement (fitness, violation and travelling
distance per path, the problem's check). jaxarm keeps per restart the path it would report, by
the study's constraint rule (death penalty: the fittest; feasibility rules: a free path before
any colliding one, then the least violation times travelling distance, as
``constraints.path_measures`` ranks them), for the escape iteration, best fitness and
violation, best path and curves that it records for the PSO; the optimiser's own ranking is its
business.

The functions must be traceable by JAX (jax.numpy, ``jax.random``, ``lax``; no Python branches
on values), and ``ask`` and ``tell`` must give back a state of the structure, shapes and dtypes
that ``init`` made. The compiled program is specialised on the object, and what its functions
read of it is compiled in at its first use: the same object (or an equal one, for a type that
defines equality and a hash, as a NamedTuple does) reuses the program; to change a setting,
make a new object.
"""

from __future__ import annotations

import operator
from typing import Any, NamedTuple, Protocol, runtime_checkable

import jax
import jax.numpy as jnp

from jaxarm._compile.jit import rank_promotion_allowed
from jaxarm.optim.base import Best, Optimizer, StepInfo, no_best, rule_cost, told_best
from jaxarm.optim.constraints import path_measures

MEMBERS = ("label", "population", "init", "ask", "tell")


@runtime_checkable
class OptimizerProtocol(Protocol):
    """What ``solve`` and ``escape_study`` accept as a method of your own (module docstring);
    subclassing it is optional: any object with these members will do."""

    label: str  # its name in tables, CSV and JSON (no ':' or ',')
    population: int  # paths asked per iteration, >= 2

    def init(self, key: jax.Array, low: jax.Array, high: jax.Array) -> Any:
        """A restart's state (a pytree) from its key and the init range, each (n_free,)."""

    def ask(self, key: jax.Array, state: Any) -> tuple[jax.Array, Any]:
        """The next paths, shape (population, n_free), and the state."""

    def tell(self, state: Any, x: jax.Array, evaluation) -> Any:
        """The state after x's ``jaxarm.Evaluation`` (fields of shape (population,))."""


def looks_like_optimizer(method) -> bool:
    """Whether ``method`` means to be one (has ``init``, ``ask`` or ``tell``), so that an error
    can say which member it lacks."""
    return not isinstance(method, str) and any(hasattr(method, m) for m in ("init", "ask", "tell"))


class CustomConfig:
    """A user's optimiser as a method's config: the compiled search's static rule, equal and
    hashed as the optimiser is (by its type and value when it defines them, as a NamedTuple
    does; else by identity)."""

    __slots__ = ("optimizer",)

    def __init__(self, optimizer):
        self.optimizer = optimizer

    def _key(self):
        try:
            hash(self.optimizer)
        except TypeError:  # a mutable dataclass: by identity
            return type(self.optimizer), id(self.optimizer)
        return type(self.optimizer), self.optimizer

    def __eq__(self, other) -> bool:
        return isinstance(other, CustomConfig) and other._key() == self._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __repr__(self) -> str:
        return f"CustomConfig({self.label!r})"

    @property
    def label(self) -> str:
        return self.optimizer.label

    @property
    def population(self) -> int:
        return operator.index(self.optimizer.population)

    @property
    def velocity_rule(self) -> str:
        """Its kind in reports, as a ``PSOConfig``'s update rule."""
        return "own optimiser"

    def params(self) -> tuple:
        """No coefficients as data."""
        return ()

    def rules(self) -> "CustomConfig":
        return self

    def validate(self) -> "CustomConfig":
        """The config, or a ValueError naming the member that breaks the protocol."""
        if isinstance(self.optimizer, type):
            raise ValueError(f"method {self.optimizer.__name__} is a class: pass an instance, "
                             f"{self.optimizer.__name__}()")
        missing = [m for m in MEMBERS if not hasattr(self.optimizer, m)]
        if missing:
            raise ValueError(f"method {type(self.optimizer).__name__} (an object) lacks "
                             f"{', '.join(missing)}: an optimiser needs {', '.join(MEMBERS)}")
        label = self.optimizer.label
        if not isinstance(label, str) or not label.strip() or ":" in label or "," in label:
            raise ValueError(f"an optimiser's label must be a name without ':' or ',', "
                             f"got {label!r}")
        population = self.optimizer.population
        try:
            valid = not isinstance(population, bool) and operator.index(population) >= 2
        except TypeError:
            valid = False
        if not valid:
            raise ValueError(f"population of {label!r} must be an int >= 2, got {population!r}")
        for name in ("init", "ask", "tell"):
            function = getattr(self.optimizer, name)
            if not callable(function):
                raise ValueError(f"{name} of {label!r} must be a function, got {function!r}")
        return self

    def _asdict(self) -> dict:
        """What a JSON record keeps of it: its label (the code is not saved)."""
        return {"optimizer": self.label}


class CustomState(NamedTuple):
    """The optimiser's own state and the path jaxarm would report."""

    inner: object
    best: Best


def custom_swarm(config: CustomConfig, evaluate_fn, low, high, *, constraint) -> Optimizer:
    """The user's optimiser as a ``base.Optimizer`` (module docstring).

    Args:
      config: the optimiser.
      evaluate_fn: paths (population, n_free) -> ``jaxarm.Evaluation`` of shape (population,).
      low, high: init range, shape (n_free,).
      constraint: int32 scalar, ``constraint_index`` of "death" or "feasibility" (data).
    """
    # the user's code may broadcast arrays of different ranks, as NumPy code does
    initial, asked, told = (rank_promotion_allowed(getattr(config.optimizer, name))
                            for name in ("init", "ask", "tell"))
    shape = (config.population,) + low.shape

    def kept(name: str, before, after):
        """``after``, or a ValueError where ``name`` changed the state's structure, a shape or a
        dtype (a scan carries the state from one iteration to the next)."""
        def types(tree):
            leaves, structure = jax.tree_util.tree_flatten_with_path(tree)
            return structure, [(jax.tree_util.keystr(path), jnp.shape(leaf),
                                jnp.result_type(leaf)) for path, leaf in leaves]
        (was, old), (now, new) = types(before), types(after)
        if was != now:
            raise ValueError(f"{name} of {config.label!r} must give back a state of init's "
                             f"structure {was}, got {now}")
        for (path, *type_before), (_, *type_after) in zip(old, new):
            if type_before != type_after:
                raise ValueError(f"{name} of {config.label!r} changed state{path} from "
                                 f"{type_before[1]}{list(type_before[0])} to "
                                 f"{type_after[1]}{list(type_after[0])}: give back what init "
                                 f"made")
        return after

    def asked_pair(key, state):
        """``ask``'s (x, state), or a ValueError where it gives back something else."""
        pair = asked(key, state)
        if not (isinstance(pair, tuple) and len(pair) == 2):
            got = (f"an array of shape {tuple(pair.shape)}" if hasattr(pair, "shape")
                   else type(pair).__name__)
            raise ValueError(f"ask of {config.label!r} must return (x, state), got {got}")
        return pair

    def checked(x):
        if getattr(x, "shape", None) != shape:
            raise ValueError(f"ask of {config.label!r} must return x of shape {shape} "
                             f"(population, n_free), got {getattr(x, 'shape', x)!r}")
        return jnp.asarray(x, low.dtype)

    def init(key):
        init_key, ask_key = jax.random.split(key)
        state = initial(init_key, low, high)
        x, inner = asked_pair(ask_key, state)
        x, inner = checked(x), kept("ask", state, inner)
        return CustomState(inner, no_best(x)), x

    def tell(state: CustomState, x, evaluation, iteration) -> tuple[CustomState, StepInfo]:
        inner = kept("tell", state.inner, told(state.inner, x, evaluation))
        measured = path_measures(evaluation.fitness, evaluation.violation, evaluation.distance)
        best, info = told_best(state.best, x, rule_cost(measured, constraint), measured)
        return CustomState(inner, best), info

    def ask(key, state: CustomState):
        x, inner = asked_pair(key, state.inner)
        return CustomState(kept("ask", state.inner, inner), state.best), checked(x)

    return Optimizer(init=init, tell=tell, ask=ask, measure=evaluate_fn)


class RecordedOptimizer(NamedTuple):
    """A user's optimiser as a saved ``Result`` names it (``CustomConfig._asdict``): the label
    alone, for reports; it cannot run again without the object."""

    optimizer: str  # the label

    @property
    def velocity_rule(self) -> str:
        return "own optimiser"

    def validate(self):
        raise ValueError(f"a record names the optimiser {self.optimizer!r} but keeps no code: "
                         f"pass the optimiser object itself as the method")
