"""Where feasibility-rule swarms get stuck on paper-case-1: the restarts that do not escape,
and whether their end point is a local minimum of the violation.

Preset A, feasibility rules, the paper's sampled check; prints the failing restarts' end points
and violations, random probes around the first one (2,000 per standard deviation), and the
violation along the straight line from it to the best free path.
"""

import argparse

import numpy as np

import jaxarm


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--restarts", type=int, default=40)
    args = parser.parse_args()
    problem = jaxarm.load_scenario("paper-case-1", collision="sampled")
    result = jaxarm.solve(problem, "A", constraint="feasibility", n_restarts=args.restarts,
                          seed=0)
    outcome = result.restarts
    stuck = ~outcome.feasible
    print(f"{stuck.sum()} of {args.restarts} restarts did not escape")
    if not stuck.any():
        return
    for x, violation in zip(outcome.best_x[stuck][:5], outcome.best_violation[stuck][:5]):
        print(f"  end point {np.round(x.astype(float), 1).tolist()}, violation {violation:.4f} cm")
    trapped = outcome.best_x[stuck][0]
    own = float(jaxarm.violation(problem, trapped))
    theta = np.asarray(jaxarm.joint_path(problem, trapped, np.linspace(0, 1, 11)), float)
    print(f"first one: violation {own:.4f} cm; joint 1 at r = 0, 0.1, ..., 1: "
          f"{np.round(theta[:, 0], 2).tolist()}")
    rng = np.random.default_rng(0)
    for scale in (1, 5, 20, 50):
        probes = trapped + scale * rng.standard_normal((2000, problem.n_free))
        violation = np.asarray(jaxarm.violation(problem, probes))
        print(f"  2,000 probes at sd {scale}: lowest violation {violation.min():.4f} cm, "
              f"{(violation == 0).mean():.1%} free")
    free = outcome.best_x[result.best_restart]
    t = np.linspace(0.0, 1.0, 41)[:, None]
    line = np.asarray(jaxarm.violation(problem, (1 - t) * trapped + t * free))
    print(f"on the line to the best free path: violation rises to {line.max():.4f} cm, "
          f"first zero at t = {float(t[np.argmax(line == 0), 0]):.3f}")


if __name__ == "__main__":
    main()
