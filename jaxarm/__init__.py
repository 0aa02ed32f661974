"""jaxarm: smooth, collision-free joint paths for planar arms, searched by batched PSO in JAX.

Quick start::

    import jaxarm
    problem = jaxarm.load_scenario("paper-case-2")
    jaxarm.fitness(problem, [66.7388, -28.1028, -9.8855])   # 0.1946, the paper's Table 3

The names below are loaded on first use, so ``import jaxarm`` (and the ``jaxarm`` command's
``--help``) does not import JAX.

Layout. Data flows one way, scenario file -> ``Problem`` -> checks -> optimiser -> ``Result`` ->
study, plot, report, CLI, and each layer imports only the ones before it:

- ``jaxarm._compile``: how programs are compiled (``jit``, stored programs, the persistent
  cache, batch padding). It imports nothing else of jaxarm and knows nothing of arms.
- ``jaxarm.model``: the arm, the obstacle world, the polynomial paths, dynamics and the
  ``Problem`` that binds them. No collision check, no optimiser.
- ``jaxarm.checks``: what a path scores: the sampled and certified collision checks, joint
  limits, and ``fitness`` / ``violation`` / ``certify`` over any batch.
- ``jaxarm.optim``: the optimiser protocol (``optim.base``: ``init``, ``ask``, ``tell``), PSO
  and the evosax adapter that implement it, the constraint rules, the compiled restart loop
  that runs it, the method grammar and its one parser (``optim.methods``), and gradient
  ``refine``. They see a problem only through ``jaxarm.checks.evaluate``.
- Top level: what users call: ``solve`` (``search``), ``escape_study`` (``study``),
  ``stats``, ``feasible_fraction``, ``Trajectory``, ``plot``, ``cli``.
- ``jaxarm.io`` (scenario files, saved runs) and ``jaxarm.paper`` (the paper's numbers, the
  reconstruction of its scenes, the report): the only places that read or write files.
- ``jaxarm.testing``: shapely oracles for tests and benchmarks; nothing else imports it.
"""
import importlib

__version__ = "0.1.0"

# public name -> the module that defines it
_EXPORTS = {
    "Arm": "jaxarm.model.arm",
    "inverse_kinematics": "jaxarm.model.poses",
    "joint_positions": "jaxarm.model.arm",
    "enable_compilation_cache": "jaxarm._compile.cache",
    "COLLISION_MODES": "jaxarm.choices",
    "CONSTRAINTS": "jaxarm.choices",
    "Certificate": "jaxarm.checks.evaluate",
    "Evaluation": "jaxarm.checks.evaluate",
    "evaluate": "jaxarm.checks.evaluate",
    "Problem": "jaxarm.model.problem",
    "certify": "jaxarm.checks.evaluate",
    "coefficients": "jaxarm.model.path_functions",
    "collides": "jaxarm.checks.evaluate",
    "collision_witness": "jaxarm.checks.evaluate",
    "Witness": "jaxarm.checks.witness",
    "fitness": "jaxarm.checks.evaluate",
    "joint_path": "jaxarm.model.path_functions",
    "share_capacities": "jaxarm.model.problem",
    "travelling_distance": "jaxarm.model.path_functions",
    "violation": "jaxarm.checks.evaluate",
    "raise_degree": "jaxarm.model.path",
    "FeasibleFraction": "jaxarm.feasible",
    "feasible_fraction": "jaxarm.feasible",
    "OptimizerProtocol": "jaxarm.optim.custom",
    "PRESETS": "jaxarm.optim.pso",
    "PSOConfig": "jaxarm.optim.pso",
    "ScenarioError": "jaxarm.io.scenario_files",
    "available_scenarios": "jaxarm.io.scenario_files",
    "load_scenario": "jaxarm.io.scenario_files",
    "problem_from_table": "jaxarm.io.scenario_files",
    "save_scenario": "jaxarm.io.scenario_files",
    "RefineResult": "jaxarm.optim.refine",
    "refine": "jaxarm.optim.refine",
    "RestartOutcome": "jaxarm.optim.restarts",
    "Result": "jaxarm.search",
    "SavedRun": "jaxarm.io.runs",
    "load_run": "jaxarm.io.runs",
    "solve": "jaxarm.search",
    "Study": "jaxarm.study",
    "Variant": "jaxarm.optim.methods",
    "escape_study": "jaxarm.study",
    "World": "jaxarm.model.world",
    "clutter": "jaxarm.model.clutter",
    "load_map": "jaxarm.io.occupancy_maps",
    "Trajectory": "jaxarm.trajectory",
    "TrajectoryPoint": "jaxarm.trajectory",
    "min_duration": "jaxarm.trajectory",
}
_RENAMED = {"available_scenarios": "available", "evaluate": "evaluate_paths"}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'jaxarm' has no attribute {name!r}")
    module = importlib.import_module(_EXPORTS[name])
    value = getattr(module, _RENAMED.get(name, name))
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
