"""Method names: the one grammar that ``solve``, ``escape_study`` and the CLI read.

    method      name[":" constraint]
    name        "A" | "B" | "C", a topology suffix ("-ring", "-global-ring"), fields in
                brackets ("A-ring[inertia_end=0.4]"): ``pso.resolve``;
                or "evosax:<Strategy>": ``evosax_adapter.resolve``
    constraint  "death" | "feasibility" | "epsilon" | "penalty": ``jaxarm.optim.constraints``

A ``PSOConfig`` or ``StrategyConfig`` may stand for the name; the constraint then comes from
the caller.
"""

from __future__ import annotations

from typing import NamedTuple

from jaxarm.choices import CONSTRAINTS, one_of
from jaxarm.optim import evosax_adapter, pso


class Variant(NamedTuple):
    """A method under a constraint rule, and its label: one row of a study, one ``solve``."""

    label: str  # e.g. "A", "A:feasibility", "custom", "evosax:CMA_ES"
    config: pso.PSOConfig | evosax_adapter.StrategyConfig
    constraint: str

    @property
    def name(self) -> str:
        """The label without its constraint: "A" for "A:feasibility"."""
        suffix = ":" + self.constraint
        return self.label[:-len(suffix)] if self.label.endswith(suffix) else self.label


def parse_method(method, constraint: str = "death", custom_label: str = "custom") -> Variant:
    """``method`` as a validated ``Variant``.

    Args:
      method: a name of the grammar above, a ``PSOConfig``, a ``StrategyConfig`` or a
        ``Variant``.
      constraint: the rule when ``method`` names none.
      custom_label: the label of a ``PSOConfig`` (or ``StrategyConfig``-less custom config).

    Returns:
      ``Variant``; its label carries the rule unless it is the death penalty.

    Raises:
      ValueError: naming the method (unknown name, field or rule; a rule evosax lacks).

    Examples:
      >>> parse_method("A-ring:feasibility").constraint
      'feasibility'
    """
    if isinstance(method, Variant):
        one_of("constraint", method.constraint, CONSTRAINTS)
        variant = method._replace(config=evosax_adapter.resolve_method(method.config))
    else:
        if isinstance(method, str):  # "A:feasibility", "evosax:CMA_ES:feasibility"
            evosax = evosax_adapter.is_strategy(method)
            prefix = evosax_adapter.PREFIX if evosax else ""
            name, colon, named = method[len(prefix):].partition(":")
            rule = one_of("constraint", named if colon else constraint, CONSTRAINTS)
            name = prefix + name
            config = evosax_adapter.resolve(name) if evosax else pso.resolve(name)
        else:
            rule = one_of("constraint", constraint, CONSTRAINTS)
            if isinstance(method, evosax_adapter.StrategyConfig):
                config = method.validate()
                name = evosax_adapter.PREFIX + config.strategy
            else:
                config, name = pso.resolve(method), custom_label
        variant = Variant(name if rule == "death" else f"{name}:{rule}", config, rule)
    evosax_adapter.check_constraint(variant.config, variant.constraint, variant.label)
    return variant


def search_variant(method, constraint: str | None) -> Variant:
    """``parse_method`` for one search (``solve``, ``jaxarm solve``): ``constraint=None``
    takes the rule the method names, else the death penalty; a method that names another rule
    than ``constraint`` is a ValueError naming both."""
    variant = parse_method(method, "death" if constraint is None else constraint)
    if constraint is not None and variant.constraint != constraint:
        raise ValueError(f"method {method!r} names constraint {variant.constraint!r} but "
                         f"constraint={constraint!r}: give the rule once")
    return variant
