"""Where feasibility-rule swarms got stuck on paper-case-1 when the rules compared the depth of
a collision alone, and why comparing the depth times the travelling distance avoids it.

Preset A, feasibility rules, the paper's sampled check. First the restarts that do not escape
when the rules compare what they compare now (``constraints.path_measures``: the depth times
the distance) and when they compare the depth alone (swapped in here, in this process only).
Then, for the depth alone: the stuck restarts' end points, random probes around the first one
(2,000 per standard deviation), and both measures along the straight line from it to the best
free path.
"""

import argparse

import jax
import numpy as np

import jaxarm
from jaxarm.optim import constraints


def depth_alone(fitness, violation, distance):
    """What the rules compared before: the violation without the distance."""
    return constraints.Measured(objective=1.0 / distance, fitness=fitness, ranked_violation=violation,
                                violation=violation)


def search(problem, n_restarts, measures):
    shipped = constraints.path_measures
    constraints.path_measures = measures
    jax.clear_caches()  # the search is traced again with these measures
    try:
        return jaxarm.solve(problem, "A", constraint="feasibility", n_restarts=n_restarts,
                            seed=0)
    finally:
        constraints.path_measures = shipped
        jax.clear_caches()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--restarts", type=int, default=40)
    args = parser.parse_args()
    problem = jaxarm.load_scenario("paper-case-1", collision="sampled")
    shipped = jaxarm.solve(problem, "A", constraint="feasibility", n_restarts=args.restarts,
                           seed=0)
    print(f"depth x distance (shipped): {(~shipped.restarts.feasible).sum()} of "
          f"{args.restarts} restarts did not escape")
    result = search(problem, args.restarts, depth_alone)
    outcome = result.restarts
    stuck = ~outcome.feasible
    print(f"depth alone: {stuck.sum()} of {args.restarts} restarts did not escape")
    if not stuck.any():
        return
    for x, violation in zip(outcome.best_x[stuck][:5], outcome.best_violation[stuck][:5]):
        print(f"  end point {np.round(x.astype(float), 1).tolist()}, depth {violation:.4f} cm")
    trapped = outcome.best_x[stuck][0]
    own = float(jaxarm.violation(problem, trapped))
    theta = np.asarray(jaxarm.joint_path(problem, trapped, np.linspace(0, 1, 11)), float)
    print(f"first one: depth {own:.4f} cm, distance "
          f"{float(jaxarm.travelling_distance(problem, trapped)):.2f}; joint 1 at r = 0, 0.1, "
          f"..., 1: {np.round(theta[:, 0], 2).tolist()}")
    own_weighted = own * float(jaxarm.travelling_distance(problem, trapped))
    rng = np.random.default_rng(0)
    for scale in (1, 5, 20, 50):
        probes = trapped + scale * rng.standard_normal((2000, problem.n_free))
        violation = np.asarray(jaxarm.violation(problem, probes))
        weighted = violation * np.asarray(jaxarm.travelling_distance(problem, probes))
        print(f"  2,000 probes at sd {scale}: lowest depth {violation.min():.4f} cm, "
              f"{(violation == 0).mean():.1%} free; depth x distance lower than the trap's "
              f"({own_weighted:.2f}) in {(weighted < own_weighted).mean():.1%}")
    free = shipped.restarts.best_x[shipped.best_restart]
    t = np.linspace(0.0, 1.0, 41)[:, None]
    line = (1 - t) * trapped + t * free
    depth = np.asarray(jaxarm.violation(problem, line))
    weighted = depth * np.asarray(jaxarm.travelling_distance(problem, line))
    first_free = int(np.argmax(depth == 0))
    print(f"on the line to the best free path (first free at t = {t[first_free, 0]:.3f}):")
    print(f"  depth: {depth[0]:.4f} cm at the trap, rises to {depth.max():.4f} cm")
    rises = np.diff(weighted[:first_free]) > 0
    print(f"  depth x distance: {weighted[0]:.2f} at the trap, falls in "
          f"{(~rises).sum()} of {rises.size} steps before the first free point")


if __name__ == "__main__":
    main()
