"""Method names: the one grammar that ``solve``, ``escape_study`` and the CLI read, and its one
parser, ``parse_method`` (``parse_methods`` for a study's list).

    method      name[":" constraint]
    name        "A" | "B" | "C" (``pso.PRESETS``), with a topology suffix ("-ring",
                "-global-ring") and fields in brackets ("A-ring[inertia_end=0.4]", any
                ``PSOConfig`` field, comma-separated; ``velocity_clamp=none`` for no clamp);
                or "evosax:<Strategy>" (``jaxarm.optim.evosax_adapter``)
    constraint  "death" | "feasibility" | "epsilon" | "penalty": ``jaxarm.optim.constraints``

A ``PSOConfig`` or ``StrategyConfig`` may stand for the name, and so may a user's own optimiser
(``jaxarm.optim.custom``: any object with ``label``, ``population``, ``init``, ``ask`` and
``tell``, labelled by its ``label``); the constraint then comes from the caller.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

from jaxarm._validate import positive_int
from jaxarm.choices import CONSTRAINTS, PSO_METHODS, TOPOLOGY_SUFFIXES, one_of
from jaxarm.optim import custom, evosax_adapter, pso
from jaxarm.optim.custom import CustomConfig, RecordedOptimizer
from jaxarm.optim.evosax_adapter import PREFIX, StrategyConfig
from jaxarm.optim.pso import PSOConfig


class Variant(NamedTuple):
    """A method under a constraint rule, and its label: one row of a study, one ``solve``."""

    label: str  # e.g. "A", "A:feasibility", "custom", "evosax:CMA_ES", "(1+8)-ES"
    config: PSOConfig | StrategyConfig | CustomConfig
    constraint: str

    @property
    def name(self) -> str:
        """The label without its constraint: "A" for "A:feasibility"."""
        suffix = ":" + self.constraint
        return self.label[:-len(suffix)] if self.label.endswith(suffix) else self.label


def parse_method(method, constraint: str | None = None, *, default_constraint: str = "death",
                 custom_label: str = "custom") -> Variant:
    """``method`` as a validated ``Variant``.

    Args:
      method: a name of the grammar above, a ``PSOConfig``, a ``StrategyConfig``, a user's
        optimiser (``jaxarm.optim.custom``) or a ``Variant``.
      constraint: the rule the caller asks for (``solve``'s ``constraint``): a method that
        names another is a ValueError naming both. None: the rule the method names, else
        ``default_constraint``.
      default_constraint: the rule of a method that names none (a study's ``constraint``).
      custom_label: the label of a ``PSOConfig``.

    Returns:
      ``Variant``; its label carries the rule unless it is the death penalty.

    Raises:
      ValueError: naming the method (unknown name, field or rule; a rule evosax lacks).

    Examples:
      >>> parse_method("A-ring:feasibility").constraint
      'feasibility'
      >>> parse_method("B-ring").config == pso.PRESETS["B"]._replace(topology="ring")
      True
      >>> parse_method("A-ring[inertia_end=0.4]").config.inertia_end
      0.4
    """
    fallback = default_constraint if constraint is None else constraint
    if isinstance(method, Variant):
        rule = one_of("constraint", method.constraint, CONSTRAINTS)
        variant = method._replace(config=_config(method.config, method.config))
    else:
        if isinstance(method, str):  # "A:feasibility", "evosax:CMA_ES:feasibility"
            prefix = PREFIX if _names_evosax(method) else ""
            name, colon, named = method[len(prefix):].partition(":")
            rule = one_of("constraint", named if colon else fallback, CONSTRAINTS)
            name = prefix + name
            config = _config(name, name)
        else:  # a config
            rule = one_of("constraint", fallback, CONSTRAINTS)
            config = _config(method, method)
            name = (PREFIX + config.strategy if isinstance(config, StrategyConfig)
                    else config.label if isinstance(config, CustomConfig) else custom_label)
        variant = Variant(name if rule == "death" else f"{name}:{rule}", config, rule)
    if (isinstance(variant.config, (StrategyConfig, CustomConfig))
            and rule not in evosax_adapter.STRATEGY_CONSTRAINTS):
        raise ValueError(f"constraint of {variant.label} must be one of "
                         f"{evosax_adapter.STRATEGY_CONSTRAINTS} (evosax strategies and your "
                         f"own optimisers: jaxarm keeps their best path by one of these), "
                         f"got {rule!r}")
    if constraint is not None and rule != constraint:
        raise ValueError(f"method {method!r} names constraint {rule!r} but "
                         f"constraint={constraint!r}: give the rule once")
    return variant


def parse_methods(methods: Sequence, default_constraint: str) -> list[Variant]:
    """A study's rows: ``parse_method`` of each entry (names, ``PSOConfig``s, ``StrategyConfig``s,
    users' optimisers or ``Variant``s; one of them alone is a list of one).

    Entries that name no constraint get ``default_constraint``. A ``PSOConfig`` is labelled
    "custom", the next ones "custom-2", "custom-3", ...; a ``Variant`` keeps its own label.
    Labels must be unique.
    """
    if isinstance(methods, (str, PSOConfig, Variant, StrategyConfig, CustomConfig,
                            RecordedOptimizer)) or custom.looks_like_optimizer(methods):
        methods = [methods]  # one method, not its characters or fields
    variants, n_custom = [], 0
    for method in methods:
        n_custom += isinstance(method, PSOConfig)
        variant = parse_method(method, default_constraint=default_constraint,
                               custom_label="custom" if n_custom <= 1 else f"custom-{n_custom}")
        if any(v.label == variant.label for v in variants):
            raise ValueError(f"methods must have unique labels, got {variant.label!r} twice")
        variants.append(variant)
    if not variants:
        raise ValueError(f"methods must name at least one method, got {methods!r}")
    return variants


def _names_evosax(method: str) -> bool:
    """Whether ``method`` names an evosax strategy; a name that means evosax without that
    spelling ("evosax", "EvoSAX:CMA_ES") is a ValueError saying how to write it."""
    if not method.startswith(PREFIX) and method.partition(":")[0].strip().lower() == PREFIX[:-1]:
        raise ValueError(f"method {method!r}: an evosax strategy is named "
                         f"{PREFIX}<Strategy>, such as {PREFIX}CMA_ES"
                         + ("" if evosax_adapter.available() else f"; {evosax_adapter.MISSING}"))
    return method.startswith(PREFIX)


def _config(name, method) -> PSOConfig | StrategyConfig | CustomConfig:
    """The validated config that a name without its rule (or a config, or an optimiser) stands
    for; ``method`` is what error messages quote."""
    if isinstance(name, (PSOConfig, StrategyConfig, CustomConfig, RecordedOptimizer)):
        return name.validate()
    if custom.looks_like_optimizer(name):  # says which member it lacks, if any
        config = CustomConfig(name).validate()
        if config.label.partition("[")[0] in PSO_METHODS or config.label.startswith(PREFIX):
            raise ValueError(f"an optimiser's label must not be a built-in method's name, got "
                             f"{config.label!r}")
        return config
    if not isinstance(name, str):
        raise ValueError(f"method must be a name, a PSOConfig or an optimiser with "
                         f"{', '.join(custom.MEMBERS)}, got {method!r}")
    if name.startswith(PREFIX):
        strategy = name[len(PREFIX):]
        return StrategyConfig(evosax_adapter.ALIASES.get(strategy, strategy)).validate()
    preset_name, bracket, fields = name.partition("[")
    if preset_name in PSO_METHODS and bracket and not fields.endswith("]"):
        raise ValueError(f"method {method!r}: the brackets must close at its end, as in "
                         f"A-ring[inertia_end=0.4]")
    if preset_name not in PSO_METHODS:
        raise ValueError(f"method must be one of {PSO_METHODS}, optionally with fields in "
                         f"brackets such as A-ring[inertia_end=0.4] and a constraint rule "
                         f"after ':' (A:feasibility), an evosax strategy ({PREFIX}CMA_ES), "
                         f"a PSOConfig or an optimiser object, got {method!r}")
    preset, _, topology = preset_name.partition("-")
    config = pso.PRESETS[preset]._replace(
        topology=TOPOLOGY_SUFFIXES.get("-" + topology, "global"))
    if not bracket:
        return config.validate()
    config = config._replace(**_fields_in_brackets(method, fields[:-1]))
    try:  # a value changed in brackets is the method's: named with it
        return config.validate()
    except ValueError as error:
        raise ValueError(f"method {method!r}: {error}") from None


def _fields_in_brackets(method: str, text: str) -> dict:
    """``"inertia_end=0.4,topology=ring"`` as PSOConfig field values (numbers as floats)."""
    changed = {}
    for item in text.split(","):
        field, equals, value = (part.strip() for part in item.partition("="))
        if field not in PSOConfig._fields or not equals or not value:
            raise ValueError(f"method {method!r}: each change in brackets must be FIELD=VALUE "
                             f"with FIELD one of {PSOConfig._fields}, got {item!r}")
        if field in changed:
            raise ValueError(f"method {method!r}: {field} is changed twice")
        if isinstance(PSOConfig._field_defaults[field], str):
            changed[field] = value
        elif field == "velocity_clamp" and value.lower() == "none":
            changed[field] = None
        else:
            try:
                changed[field] = float(value)
            except ValueError:
                raise ValueError(f"method {method!r}: {field} must be a number, "
                                 f"got {value!r}") from None
    return changed


def swarm_size(variants: Sequence[Variant], n_particles: int | None, default: int) -> int:
    """The paths per iteration of a call's methods: ``n_particles``; None: the population of
    the user's own optimisers among ``variants``, else ``default``. Every method of a call gets
    the same budget, so an optimiser whose population differs is a ValueError saying so."""
    if n_particles is not None:
        positive_int("n_particles", n_particles, minimum=2)
    populations = {v.config.population: v.label for v in variants
                   if isinstance(v.config, CustomConfig)}
    if not populations:
        return default if n_particles is None else n_particles
    if n_particles is None:
        (first, label), *others = populations.items()
        if others:
            raise ValueError(f"method {label!r} asks {first} paths per iteration and "
                             f"{others[0][1]!r} {others[0][0]}: every method of a call runs the "
                             f"same number (give optimisers of one population)")
        return first
    for population, label in populations.items():
        if population != n_particles:
            raise ValueError(f"method {label!r} asks {population} paths per iteration but "
                             f"n_particles={n_particles!r}: every method of a call runs the same "
                             f"number (give n_particles={population}, or leave it out)")
    return n_particles
