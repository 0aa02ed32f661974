"""How the shipped paper scenarios were reconstructed from the paper's published numbers.

Runs ``jaxarm.paper.reconstruct`` end to end and prints markdown (the source of RESULTS.md's
"Reconstructing the paper's scenarios" section and of the comments in paper-case-*.toml):

1. case 1's start and goal postures fitted to Table 2's 17 fitness values (end-effector held at
   (50, -10) and (50, 40)), with the residual per published value;
2. case 1's obstacles: the largest circles that keep Table 2's paths clear (a dense sweep, 0.5 cm
   gap), three picked greedily to block the most of the initial range and the obstacle-free
   optimum; then the death-penalty escape rates of A, B and C over ``--seeds`` seeds;
3. case 1's better paths: circles that keep Table 2's motions 0.05 cm clear and block every
   free path above 0.1797 that a grid and the default search find, round after round
   (``blocking.block_better_paths``); then, up to 8 circles, the ones that block the most
   free paths above 0.165, the band only the paper's A runs reached; the checks of the result (Table 2's sets, a6 = 0, grids and
   searches for free paths above 0.18 under both checks, ``blocking.prove_blocked``) and
   the death-penalty escape rates again;
4. cases II and III's obstacle: circles that keep the 18 sets the paper calls feasible clear
   under its 101-sample check (0.05 cm gap), picked to block the 6 it calls infeasible and the
   obstacle-free optimum; label agreement with one and two circles, and under a dense sweep.

    python benchmarks/reconstruct_scenarios.py            # about 20 minutes on 2 CPU cores
    python benchmarks/reconstruct_scenarios.py --restarts 100
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import blocking  # benchmarks/blocking.py, beside this file
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


def obstacles_case_1(fit, n_restarts: int) -> jaxarm.Problem:
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
    return problem


# Case 1's better paths. The target: no certified-free path above TARGET, the paper's best
# (0.1774) plus a margin: the paper's best run need not have reached the best path its layout
# left free, and our obstacles keep Table 2's motions clear, so paths close to them stay free.
# The searches block every free path above DESIGN, a little under the target for what a search
# can miss; prove_blocked then checks the target itself.
TARGET, DESIGN, GAP = 0.18, 0.1797, 0.05
BAND = 0.165  # no published fitness lies between 0.1592 (B and C) and 0.1695 (A)
BAND_PATHS = 20_000
CIRCLE_SLOTS = 8  # one compiled program size (capacities are powers of two)
BOX = ([30.0, -100.0, -100.0], [110.0, -30.0, 60.0])  # holds every free path found, and more


def better_paths_case_1(problem: jaxarm.Problem, n_restarts: int) -> None:
    table_2 = a6_array(published.CASE_1)
    print("## Case 1 better paths\n")
    began = time.perf_counter()
    def log(line: str) -> None:
        print(f"    {time.perf_counter() - began:5.0f} s  {line}")

    print(f"Blocking every free path above {DESIGN} (gap {GAP} cm from Table 2's motions):\n")
    better = blocking.block_better_paths(problem, table_2, DESIGN, *BOX, gap=GAP,
                                         max_obstacles=CIRCLE_SLOTS, log=log)
    n_left = CIRCLE_SLOTS - len(problem.world.circles) - len(better.layout.circles)
    band = blocking.free_paths_above(better.problem, BAND, *BOX, step=1.0)
    # at most BAND_PATHS of them, drawn at random, to keep each trial circle's count quick
    band_x = band.x[np.random.default_rng(0).permutation(len(band.x))[:BAND_PATHS]]
    print(f"\nNarrowing: {len(band.x)} free paths above {BAND} (grid every 1; {len(band_x)} "
          f"drawn), the {n_left} circles that block the most of them:\n")
    narrow = blocking.block_paths(better.problem, table_2, band_x, gap=GAP,
                                  max_obstacles=n_left, n_probe=16, tries=6, log=log)
    added = better.layout.circles + narrow.circles
    # centres to 0.01 cm, radii down to 0.01 cm: the gap shrinks by at most 0.02 cm
    added = [(round(x, 2), round(y, 2), float(np.floor(r * 100) / 100)) for x, y, r in added]
    final = problem.replace(world=jaxarm.World(circles=problem.world.circles + tuple(added)),
                            capacities=None)
    print(f"\nCircles added: {added}\n")
    check_case_1(final, table_2, n_restarts)


def check_case_1(problem: jaxarm.Problem, table_2, n_restarts: int) -> None:
    certified = problem.replace(collision="certified")
    ours = np.asarray(jaxarm.fitness(problem, table_2), np.float64)
    paper = np.array([s.fitness for s in published.CASE_1])
    free = np.asarray(jaxarm.certify(certified, table_2).free)
    zero = [float(jaxarm.fitness(p, [0.0, 0.0, 0.0])) for p in (problem, certified)]
    clearance = (blocking.nearest_distances(
        np.array(problem.world.circles)[:, :2], blocking.motion_segments(problem, table_2, 4001),
        exact=True) - np.array(problem.world.circles)[:, 2])
    print(f"Table 2: {int((ours > 0).sum())}/17 free sampled, {int(free.sum())}/17 certified, "
          f"worst relative fitness error {np.max(np.abs(ours - paper) / paper):.1e}; each "
          f"circle's clearance from the 17 motions (4,001 times): "
          f"{np.round(clearance, 3).tolist()} cm; a6 = 0: "
          f"{'blocked' if max(zero) == 0 else 'FREE'} under both checks\n")
    print(f"Free paths above {TARGET}:\n")
    print("| search | check | grid points above 0.17 without obstacles, or restarts | free above "
          "the target | best free fitness |")
    print("|---|---|---|---|---|")
    for name, check, kwargs in [
            ("grid every 0.25 over the box", problem, {"low": BOX[0], "high": BOX[1], "step": 0.25}),
            ("grid every 0.05 near Table 2's best", problem,
             {"low": [48, -62, -14], "high": [60, -52, 16], "step": 0.05}),
            (f"default search, {n_restarts} restarts x 2 methods", problem,
             {"low": [0] * 3, "high": [0] * 3, "step": 1.0, "n_restarts": n_restarts, "seed": 7}),
            (f"default search, {n_restarts} restarts x 2 methods", certified,
             {"low": [0] * 3, "high": [0] * 3, "step": 1.0, "n_restarts": n_restarts, "seed": 8})]:
        found = blocking.free_paths_above(check, 0.17, **kwargs)
        examined = found.n_grid if not found.n_restarts else found.n_restarts
        print(f"| {name} | {check.collision} | {examined:,} | "
              f"{int((found.fitness > TARGET).sum())} | {found.best_fitness:.5f} |")
    print()
    for threshold in (TARGET, 0.1795):
        proof = blocking.prove_blocked(problem, threshold, [-128.0] * 3, [128.0] * 3,
                                          half_width=16.0, min_half_width=1 / 512)
        print(f"prove_blocked({threshold}) over [-128, 128]^3: "
              f"{'proved' if proof.proved else 'not proved'} ({len(proof.unresolved)} cubes "
              f"unresolved, better paths {'meet' if proof.meets_box else 'miss'} the box; "
              f"{proof.by_fitness:,} cubes below the threshold, {proof.by_collision:,} "
              f"colliding, smallest half-width {proof.min_half_width:g})")
    study = escape_study(problem, ["A", "B", "C"], n_restarts=n_restarts, progress=False)
    print(f"\nDeath-penalty escape over {n_restarts} seeds, sampled check: "
          + ", ".join(f"{m.variant.label} {m.escape_rate():.1%} [{m.escape_interval()[0]:.1%}, "
                      f"{m.escape_interval()[1]:.1%}]" for m in study.methods) + "\n")


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
    problem = obstacles_case_1(fit, args.restarts)
    better_paths_case_1(problem, args.restarts)
    obstacles_cases_2_and_3()
    print(f"Total {time.perf_counter() - began:.0f} s")


if __name__ == "__main__":
    main()
