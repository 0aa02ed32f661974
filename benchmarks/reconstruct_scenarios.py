"""How the shipped paper scenarios were reconstructed from the paper's published numbers.

Runs ``jaxarm.paper.reconstruct`` end to end and prints markdown (the source of RESULTS.md's
"Reconstructing the paper's scenarios" section and of the comments in paper-case-*.toml):

1. case 1's start and goal postures fitted to Table 2's 17 fitness values (end-effector held at
   (50, -10) and (50, 40)), with the residual per published value;
2. case 1's obstacles: the largest circles that keep Table 2's paths clear (a dense sweep, 0.5 cm
   gap), three picked greedily to block the most of the initial range and the obstacle-free
   optimum; then the death-penalty escape rates of A, B and C over ``--seeds`` seeds;
3. cases II and III's obstacle: circles that keep the 18 sets the paper calls feasible clear
   under its 101-sample check (0.05 cm gap), picked to block the 6 it calls infeasible and the
   obstacle-free optimum; label agreement with one and two circles, and under a dense sweep.

    python benchmarks/reconstruct_scenarios.py            # about 5 minutes on 2 CPU cores
    python benchmarks/reconstruct_scenarios.py --restarts 100
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import jaxarm
from jaxarm.paper import published, reconstruct
from jaxarm.paper.published import a6_array
from jaxarm.study import escape_study, wilson_interval

ARM = jaxarm.Arm((30.0, 30.0, 20.0))


def _circles(layout, k) -> list[tuple[float, float, float]]:
    return [tuple(round(float(v), 2) for v in circle) for circle in layout.circles[:k]]


def fit_case_1() -> reconstruct.PostureFit:
    fit = reconstruct.fit_postures(ARM, published.CASE_1_END_POINTS, published.CASE_1)
    print("## Case 1 postures\n")
    print(f"start: phi = {fit.start_phi:.6f} rad, elbow {fit.start_elbow:+d}, joints "
          f"{np.round(fit.start, 10).tolist()}")
    print(f"goal:  phi = {fit.goal_phi:.6f} rad, elbow {fit.goal_elbow:+d}, joints "
          f"{np.round(fit.goal, 10).tolist()}")
    print(f"worst relative error {fit.relative_error.max():.2e}\n")
    print("| Table 2 set | a6 | paper fitness | ours (no obstacles) | relative error |")
    print("|---|---|---|---|---|")
    for s, ours, error in zip(published.CASE_1, fit.fitness, fit.relative_error):
        print(f"| {s.source} | {list(s.a6)} | {s.fitness} | {ours:.5f} | {error:.1e} |")
    print()
    return fit


def obstacles_case_1(fit, n_restarts: int) -> None:
    base = jaxarm.Problem(arm=ARM, start=fit.start, goal=fit.goal, collision="sampled",
                          capacities=(4, 4, 4))
    candidates = reconstruct.circle_candidates(base, a6_array(published.CASE_1))
    layout = reconstruct.greedy_circles(base, candidates, 3, block=[[0.0, 0.0, 0.0]])
    print("## Case 1 obstacles\n")
    print(f"{len(candidates)} candidate circles; greedy picks (free share of "
          f"{layout.n_paths} random paths after each):\n")
    for circle, share in zip(_circles(layout, 3), layout.free_fraction):
        print(f"- circle {circle}: {share:.2%} free")
    problem = base.replace(world=jaxarm.World(circles=_circles(layout, 3)))
    verdicts = reconstruct.label_agreement(problem, published.CASE_1)
    certified = np.asarray(jaxarm.certify(problem, a6_array(published.CASE_1)).free)
    print(f"\nTable 2 paths free: {sum(v.agrees for v in verdicts)}/17 sampled, "
          f"{int(certified.sum())}/17 certified; obstacle-free optimum a6 = 0 "
          f"{'blocked' if float(jaxarm.fitness(problem, [0.0, 0.0, 0.0])) == 0 else 'FREE'}\n")
    study = escape_study(problem, ["A", "B", "C"], n_restarts=n_restarts, progress=False)
    low, high = wilson_interval(3, 7)
    print(f"Death-penalty escape over {n_restarts} seeds (paper: 3/7 each, 95 % interval "
          f"{low:.0%}-{high:.0%}):\n")
    print("| preset | escaped | 95 % interval | median escape iteration | best fitness |")
    print("|---|---|---|---|---|")
    for method in study.methods:
        s = method.summary()
        print(f"| {s['method']} | {s['escape_rate']:.1%} | [{s['ci95_low']:.1%}, "
              f"{s['ci95_high']:.1%}] | {s['escape_iter_median']} | {s['fitness_best']:.4f} |")
    print()


def obstacles_cases_2_and_3() -> None:
    case2 = jaxarm.load_scenario("paper-case-2", collision="sampled")
    base = case2.replace(world=jaxarm.World(), capacities=(4, 4, 4))
    free_sets = [s for s in published.CASE_2 if s.feasible]
    infeasible = a6_array([s for s in published.CASE_2 if not s.feasible])
    block = np.vstack([infeasible, [[0.0, 0.0, 0.0]]])
    candidates = reconstruct.circle_candidates(base, a6_array(free_sets), spacing=0.5, gap=0.05,
                                               min_radius=0.25, n_points=base.n_samples)
    blocks_any = (reconstruct.sweep_distances(base, block, candidates[:, :2], base.n_samples)
                  < candidates[:, 2]).any(axis=0)
    layout = reconstruct.greedy_circles(base, candidates[blocks_any], 2, block=block,
                                        n_paths=3000)
    dense = reconstruct.sweep_distances(base, a6_array(free_sets), candidates[:, :2], 1001).min(0)
    blockable = (reconstruct.sweep_distances(base, block[:-1], candidates[:, :2], 1001)
                 < dense - 0.05).any(axis=1)
    print("## Cases II and III obstacle\n")
    print(f"{int(blocks_any.sum())} of {len(candidates)} candidate circles block a set the "
          f"paper calls infeasible. With the feasible sets' sweep measured at 1,001 points "
          f"instead of the paper's 101, the infeasible sets that any candidate circle can "
          f"still block: "
          f"{int(blockable.sum())}/6 ({block[:-1][~blockable].tolist()} cannot).\n")
    print("| circles | labels agreeing (sampled) | disagreeing | feasible sets certified | "
          "a6 = 0 | case III optimum |")
    print("|---|---|---|---|---|---|")
    case3 = jaxarm.load_scenario("paper-case-3", collision="sampled")
    for k in (1, 2):
        world = jaxarm.World(circles=_circles(layout, k))
        problem = base.replace(world=world)
        verdicts = reconstruct.label_agreement(problem, published.CASE_2)
        wrong = [f"{list(v.published.a6)} ({v.fitness:.4f})" for v in verdicts if not v.agrees]
        certified = int(np.asarray(jaxarm.certify(problem, a6_array(free_sets)).free).sum())
        zero = "blocked" if float(jaxarm.fitness(problem, [0.0, 0.0, 0.0])) == 0 else "free"
        three = float(jaxarm.fitness(case3.replace(world=world, capacities=(4, 4, 4)),
                                     published.CASE_3[0].a6))
        print(f"| {_circles(layout, k)} | {sum(v.agrees for v in verdicts)}/24 | "
              f"{', '.join(wrong) or 'none'} | {certified}/18 | {zero} | {three:.4f} |")
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--restarts", type=int, default=500, help="escape-study seeds (case 1)")
    args = parser.parse_args()
    began = time.perf_counter()
    fit = fit_case_1()
    obstacles_case_1(fit, args.restarts)
    obstacles_cases_2_and_3()
    print(f"Total {time.perf_counter() - began:.0f} s")


if __name__ == "__main__":
    main()
