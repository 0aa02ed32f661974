"""evosax strategies on the same benchmark as the PSO: methods named ``"evosax:<Strategy>"``.

A strategy (a class of ``evosax.algorithms`` built from a population size and a solution
shape alone: ``"evosax:CMA_ES"``, ``"evosax:DE"`` for ``DifferentialEvolution`` and
``"evosax:PSO"`` are tested or tried; others are not) implements ``jaxarm.optim.base.Optimizer``, so it
runs in the restart loop of ``jaxarm.optim.restarts`` exactly like the PSO: vmapped over restarts
in one compiled program, with the same seeds, the same budget (``n_particles`` evaluations
at iteration 0, then ``n_particles`` per generation for ``n_iters`` generations) and the
escape iteration, history and best path recorded the same way.

- Iteration 0: a population-based strategy starts from ``n_particles`` paths drawn uniformly
  from the init range, like the PSO; a distribution-based one (CMA-ES, ...) from its first
  sample around a mean drawn uniformly from the range, with ``std_init`` a quarter of the
  range's mean width (pycma's usual advice), then told those samples' costs.
- Costs, minimised: under the death penalty ``-fitness`` (every colliding path 0); under
  feasibility rules ``-fitness`` for a free path and its violation (> 0; the depth times the
  distance, ``constraints.path_measures``) for a colliding one, so that a free path beats every
  colliding one and less violation beats more (Deb's rules as one number). evosax has no
  constraint handling of its own (its issues #38 and #71).
- The best path is the lowest cost seen so far (the earliest on ties).

evosax is an optional dependency (``pip install 'jaxarm[bench]'`` or ``pip install evosax``);
naming a strategy without it installed is a ValueError saying so.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxarm._compile.jit import rank_promotion_allowed
from jaxarm.optim.base import (Best, MeasureFn, Optimizer, StepInfo, no_best, on_first_iteration,
                               rule_cost, told_best)

PREFIX = "evosax:"
ALIASES = {"DE": "DifferentialEvolution", "GA": "SimpleGA"}
STRATEGY_CONSTRAINTS = ("death", "feasibility")


def available() -> bool:
    """Whether evosax is installed (without importing it)."""
    import importlib.util

    return importlib.util.find_spec("evosax") is not None


MISSING = "evosax methods need evosax: pip install 'jaxarm[bench]' (or pip install evosax)"


def _evosax_algorithms():
    try:
        from evosax import algorithms
    except ImportError:
        raise ValueError(MISSING) from None
    return algorithms


class StrategyConfig(NamedTuple):
    """An evosax strategy as a study method (hashable: it is also the program's static rule)."""

    strategy: str  # a class name of ``evosax.algorithms``, e.g. "CMA_ES"

    @property
    def velocity_rule(self) -> str:
        """The update rule's name in reports, as for a ``PSOConfig``."""
        return f"evosax {self.strategy}"

    def params(self) -> tuple:
        """No coefficients as data: the strategy's defaults are compiled in."""
        return ()

    def rules(self) -> "StrategyConfig":
        return self

    def validate(self) -> "StrategyConfig":
        """The config with its alias resolved ("DE": "DifferentialEvolution"), or a ValueError
        naming the method when evosax has no such strategy (or is not installed)."""
        name = ALIASES.get(self.strategy, self.strategy)
        algorithms = _evosax_algorithms()
        strategy = getattr(algorithms, name, None)
        if not (isinstance(strategy, type) and issubclass(
                strategy, algorithms.base.EvolutionaryAlgorithm)):
            known = sorted(set(algorithms.distribution_based_algorithms)
                           | set(algorithms.population_based_algorithms))
            raise ValueError(f"method {PREFIX + self.strategy!r}: evosax has no strategy "
                             f"{name!r}; it has {', '.join(known)} (and the aliases "
                             f"{', '.join(ALIASES)})")
        return StrategyConfig(name)


class StrategyState(NamedTuple):
    """The evosax state, the best path seen so far, and what ``tell`` needs."""

    inner: object  # the strategy's own state (a pytree; a placeholder before the first tell)
    best: Best
    tell_key: jax.Array  # the key of the next tell (or of the strategy's init)


def strategy_swarm(config: StrategyConfig, measure_fn: MeasureFn, low, high, *,
                   n_particles: int, constraint) -> Optimizer:
    """The strategy as an ``Optimizer`` (module docstring).

    Args:
      config: the strategy.
      measure_fn: paths (n_particles, n_dims) -> ``Measured`` of shape (n_particles,).
      low, high: init range, shape (n_dims,).
      n_particles: population size (static).
      constraint: int32 scalar, ``constraint_index`` of "death" or "feasibility" (data).
    """
    algorithms = _evosax_algorithms()
    strategy = getattr(algorithms, config.strategy)(population_size=n_particles,
                                                    solution=jnp.zeros_like(low))
    # evosax broadcasts arrays of different ranks: its calls are traced with that allowed
    initial, asked, told_by = (rank_promotion_allowed(getattr(strategy, name))
                               for name in ("init", "ask", "tell"))
    params = strategy.default_params
    if hasattr(params, "std_init"):
        params = params.replace(std_init=jnp.mean(high - low) / 4)
    distribution = isinstance(strategy, algorithms.distribution_based.base.
                              DistributionBasedAlgorithm)

    def init(key):
        draw, start_key, ask, tell = jax.random.split(key, 4)
        if distribution:
            mean = jax.random.uniform(draw, low.shape, low.dtype, low, high)
            x, inner = asked(ask, initial(start_key, mean, params), params)
        else:  # the strategy's state is made from the first costs: a placeholder until then
            x = jax.random.uniform(draw, (n_particles,) + low.shape, low.dtype, low, high)
            shapes = jax.eval_shape(initial, start_key, x, jnp.zeros(n_particles, x.dtype),
                                    params)
            inner = jax.tree.map(lambda leaf: jnp.zeros(leaf.shape, leaf.dtype), shapes)
        return StrategyState(inner=inner, best=no_best(x),
                             tell_key=tell if distribution else start_key), x

    def tell(state: StrategyState, x, measured, iteration) -> tuple[StrategyState, StepInfo]:
        cost = rule_cost(measured, constraint)

        def told():
            return told_by(state.tell_key, x, cost, state.inner, params)[0]

        if distribution:
            inner = told()
        else:  # the initial population makes the strategy's state
            inner = on_first_iteration(
                iteration, lambda: initial(state.tell_key, x, cost, params), told)
        best, info = told_best(state.best, x, cost, measured)
        return state._replace(inner=inner, best=best), info

    def ask(key, state: StrategyState):
        ask_key, tell_key = jax.random.split(key)
        x, inner = asked(ask_key, state.inner, params)
        return state._replace(inner=inner, tell_key=tell_key), x

    return Optimizer(init=init, tell=tell, ask=ask, measure=measure_fn)
