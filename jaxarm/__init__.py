"""jaxarm: smooth, collision-free joint paths for planar arms, searched by batched PSO in JAX.

Quick start::

    import jaxarm
    problem = jaxarm.load_scenario("paper-case-2")
    jaxarm.fitness(problem, [66.7388, -28.1028, -9.8855])   # 0.1946, the paper's Table 3

The names below are loaded on first use, so ``import jaxarm`` (and the ``jaxarm`` command's
``--help``) does not import JAX.
"""

import importlib

__version__ = "0.1.0"

# public name -> the module that defines it
_EXPORTS = {
    "Arm": "jaxarm.arm",
    "inverse_kinematics": "jaxarm.arm",
    "joint_positions": "jaxarm.arm",
    "enable_compilation_cache": "jaxarm.cache",
    "COLLISION_MODES": "jaxarm.choices",
    "CONSTRAINTS": "jaxarm.choices",
    "Certificate": "jaxarm.problem",
    "Evaluation": "jaxarm.problem",
    "Problem": "jaxarm.problem",
    "certify": "jaxarm.problem",
    "coefficients": "jaxarm.problem",
    "collides": "jaxarm.problem",
    "fitness": "jaxarm.problem",
    "joint_path": "jaxarm.problem",
    "share_capacities": "jaxarm.problem",
    "travelling_distance": "jaxarm.problem",
    "violation": "jaxarm.problem",
    "raise_degree": "jaxarm.path",
    "FeasibleFraction": "jaxarm.feasible",
    "feasible_fraction": "jaxarm.feasible",
    "PRESETS": "jaxarm.pso",
    "PSOConfig": "jaxarm.pso",
    "ScenarioError": "jaxarm.scenarios",
    "available_scenarios": "jaxarm.scenarios",
    "load_scenario": "jaxarm.scenarios",
    "problem_from_table": "jaxarm.scenarios",
    "save_scenario": "jaxarm.scenarios",
    "RefineResult": "jaxarm.polish",
    "refine": "jaxarm.polish",
    "RestartOutcome": "jaxarm.restarts",
    "Result": "jaxarm.search",
    "SavedRun": "jaxarm.search",
    "load_run": "jaxarm.search",
    "solve": "jaxarm.search",
    "Study": "jaxarm.study",
    "Variant": "jaxarm.study",
    "escape_study": "jaxarm.study",
    "World": "jaxarm.world",
    "Trajectory": "jaxarm.trajectory",
    "TrajectoryPoint": "jaxarm.trajectory",
    "min_duration": "jaxarm.trajectory",
}
_RENAMED = {"available_scenarios": "available"}

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
