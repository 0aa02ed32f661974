"""jaxarm: smooth, collision-free joint paths for planar arms, searched by batched PSO in JAX.

Quick start::

    import jaxarm
    problem = jaxarm.load_scenario("paper-case-2")
    jaxarm.fitness(problem, [66.7388, -28.1028, -9.8855])   # 0.1946, the paper's Table 3
"""

from jaxarm.arm import Arm, inverse_kinematics, joint_positions
from jaxarm.problem import (
    COLLISION_MODES,
    Certificate,
    Evaluation,
    Problem,
    certify,
    coefficients,
    collides,
    fitness,
    joint_path,
    travelling_distance,
    violation,
)
from jaxarm.path import raise_degree
from jaxarm.pso import CONSTRAINTS, PRESETS, PSOConfig
from jaxarm.scenarios import ScenarioError, available as available_scenarios, load_scenario
from jaxarm.refine import RefineResult, refine
from jaxarm.solve import Result, solve
from jaxarm.world import World

__version__ = "0.1.0"

__all__ = [
    "Arm",
    "COLLISION_MODES",
    "CONSTRAINTS",
    "Certificate",
    "Evaluation",
    "PRESETS",
    "PSOConfig",
    "Problem",
    "RefineResult",
    "Result",
    "ScenarioError",
    "World",
    "available_scenarios",
    "certify",
    "coefficients",
    "collides",
    "fitness",
    "inverse_kinematics",
    "joint_path",
    "joint_positions",
    "load_scenario",
    "raise_degree",
    "refine",
    "solve",
    "travelling_distance",
    "violation",
]
