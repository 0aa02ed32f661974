"""Problem: the paper's published values, batching, jit, dtypes and input validation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import jaxarm
from jaxarm.choices import MAX_DEGREE
import jaxarm.model.problem  # the module itself, for evaluate and vmapped_evaluate
from jaxarm.optim.restarts import is_compiled
from jaxarm.paper import published

CASE_2_FEASIBLE = [s for s in published.CASE_2 if s.feasible]


def _printed_decimals(value: float) -> int:
    return len(repr(value).split(".")[1])


@pytest.mark.parametrize("paper", CASE_2_FEASIBLE, ids=lambda s: s.source)
def test_case_2_published_fitness(case2, paper):
    # Equal at the digits the paper printed (4 significant figures, 5 for 0.19765).
    fitness = float(jaxarm.fitness(case2, paper.a6))
    assert round(fitness, _printed_decimals(paper.fitness)) == paper.fitness


def test_case_3_published_fitness(case3):
    paper = published.CASE_3[0]
    fitness = float(jaxarm.fitness(case3, paper.a6))
    assert round(fitness, _printed_decimals(paper.fitness)) == paper.fitness


@pytest.mark.parametrize("mode", ["sampled", "certified"])
def test_reconstructed_obstacle_blocks_the_free_optimum(case2, mode):
    problem = case2.replace(collision=mode)
    assert bool(jaxarm.collides(problem, [0.0, 0.0, 0.0]))
    free = ~np.asarray(jaxarm.collides(problem, [s.a6 for s in CASE_2_FEASIBLE]))
    # Under the certified check one set grazes the circle between the paper's samples.
    assert free.sum() == (18 if mode == "sampled" else 17)


def test_fitness_is_inverse_distance_when_free_and_zero_when_colliding(case2, rng):
    x = rng.uniform(-200, 200, (2000, 3))
    fitness = np.asarray(jaxarm.fitness(case2, x))
    distance = np.asarray(jaxarm.travelling_distance(case2, x))
    np.testing.assert_array_equal(distance, jaxarm.evaluate(case2, x).distance)
    programs = jaxarm.checks.evaluate._evaluate_and_certify.programs_made()
    jaxarm.travelling_distance(case2.replace(n_samples=41), x)  # runs no collision check
    assert jaxarm.checks.evaluate._evaluate_and_certify.programs_made() == programs
    violation = np.asarray(jaxarm.violation(case2, x))
    free = violation == 0
    assert 0 < free.sum() < len(x)
    np.testing.assert_allclose(fitness[free], 1 / distance[free], rtol=1e-6)
    assert np.all(fitness[~free] == 0)
    assert np.all(violation >= 0)
    np.testing.assert_array_equal(np.asarray(jaxarm.collides(case2, x)), ~free)


def test_batched_equals_looped_for_any_leading_shape(case2, rng):
    x = rng.uniform(-200, 200, (2, 3, 3))
    batched = np.asarray(jaxarm.violation(case2, x))
    assert batched.shape == (2, 3)
    looped = np.array([[float(jaxarm.violation(case2, x[i, j])) for j in range(3)]
                       for i in range(2)])
    np.testing.assert_allclose(batched, looped, rtol=1e-5, atol=1e-6)


def test_batches_are_padded_to_a_few_sizes_and_rows_do_not_depend_on_them(case2, rng):
    from jaxarm._compile.padding import LARGE_BLOCK, SMALL_BATCH, padded_size
    from jaxarm.checks.evaluate import _evaluate_and_certify

    assert [padded_size(n) for n in (0, 1, 64, 65, 4096, 4097)] == [64, 64, 64, 128, 4096, 8192]
    assert padded_size(3, smallest=16) == 16 and padded_size(3 * LARGE_BLOCK + 1) == 4 * 4096
    x = rng.uniform(-200, 200, (SMALL_BATCH + 6, 3)).astype(np.float32)
    large = [np.asarray(f(case2, x)) for f in (jaxarm.fitness, jaxarm.violation)]
    jaxarm.fitness(case2, x[:1])
    programs = _evaluate_and_certify.programs_made()
    for size in (1, 5, SMALL_BATCH):
        for f, whole in zip((jaxarm.fitness, jaxarm.violation), large):
            np.testing.assert_array_equal(np.asarray(f(case2, x[:size])), whole[:size])
    assert np.asarray(jaxarm.travelling_distance(case2, x[:2].reshape(2, 1, 3))).shape == (2, 1)
    assert jaxarm.fitness(case2, x[:0]).shape == (0,)  # run as 64 zero paths, cut away
    assert _evaluate_and_certify.programs_made() == programs


@pytest.mark.parametrize("mode", ["sampled", "certified"])
def test_jit_equals_no_jit(case2, rng, mode):
    # Eager loops run step by step in Python: few samples, a small bisection budget.
    problem = case2.replace(collision=mode, n_samples=21, certify_budget=32)
    x = jnp.asarray(rng.uniform(-200, 200, (64, 3)), dtype=jnp.float32)
    spec, arrays = problem.spec, problem.arrays
    with jax.disable_jit():
        eager = jaxarm.checks.evaluate.evaluate(spec, arrays, x)
    jitted = jax.jit(jaxarm.checks.evaluate.evaluate, static_argnums=0)(spec, arrays, x)
    for a, b in zip(eager, jitted):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-5)


@given(st.lists(st.floats(-200, 200), min_size=3, max_size=3))
def test_float32_agrees_with_float64(x):
    problem = jaxarm.load_scenario("paper-case-2")
    low = np.asarray(jaxarm.evaluate(problem, jnp.asarray(x, jnp.float32)))
    with jax.enable_x64(True):
        high = np.asarray(jaxarm.evaluate(problem, jnp.asarray(x, jnp.float64)))
    np.testing.assert_allclose(low[2], high[2], rtol=1e-5)  # distance
    # Collision verdicts can only differ within rounding of the boundary.
    if (low[1] > 0) != (high[1] > 0):
        assert max(low[1], high[1]) < 1e-3


def test_float32_paths_stay_accurate_at_the_highest_degree(case2, rng):
    """``MAX_DEGREE``'s premise (``benchmarks/degree_limit.py``): float32 angles and
    travelling distances agree with float64 there as at degree 6."""
    problem = case2.replace(degree=MAX_DEGREE)
    x = rng.uniform(-100.0, 100.0, (16, problem.n_free))
    r = np.linspace(0.0, 1.0, problem.n_samples)
    low = np.asarray(jaxarm.joint_path(problem, x.astype(np.float32), r))
    distance = np.asarray(jaxarm.travelling_distance(problem, x.astype(np.float32)))
    with jax.enable_x64(True):
        high = np.asarray(jaxarm.joint_path(problem, x, r))
        exact = np.asarray(jaxarm.travelling_distance(problem, x))
    assert np.abs(low - high).max() <= 1e-6 * np.abs(high).max()
    np.testing.assert_allclose(distance, exact, rtol=2e-6)


def test_new_obstacle_data_does_not_recompile(case2):
    moved = case2.replace(world=jaxarm.World(circles=[(-40.0, -40.0, 5.0)]))
    assert moved.spec == case2.spec
    x = jnp.zeros((4, 3))
    jaxarm.fitness(case2, x)
    before = jaxarm.checks.evaluate._evaluate_and_certify.programs_made()
    jaxarm.fitness(moved, x)
    assert jaxarm.checks.evaluate._evaluate_and_certify.programs_made() == before


ARM = jaxarm.Arm((30.0, 30.0, 20.0))


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"start": [0.0, float("nan"), 0.0]}, r"start\[1\] must be finite, got nan"),
        ({"goal": [0.0, 1.0]},
         r"goal has 2 joint angles but arm.lengths \[30.0, 30.0, 20.0\] has 3 links"),
        ({"start": [1e30, 2.0, -0.6]}, r"start\[0\] must be an angle in \[-100, 100\] rad"),
        ({"n_samples": 100}, r"n_samples must be odd .* got 100"),
        ({"n_samples": 1}, r"n_samples must be >= 3, got 1"),
        ({"degree": 5}, r"degree must be >= 6, got 5"),
        ({"degree": 6.5}, r"degree must be an integer, got 6.5"),
        ({"collision": "exact"}, r"collision must be one of .* got 'exact'"),
        ({"init_low": 5.0, "init_high": 5.0}, r"init_low must be < init_high"),
        ({"init_low": [0.0, 1.0]}, r"init_low must have 3 values, got 2"),
        ({"init_high": float("inf")}, r"init_high must be finite, got inf"),
        ({"degree": MAX_DEGREE + 1}, rf"degree must be <= {MAX_DEGREE}, got {MAX_DEGREE + 1}"),
        ({"init_low": -1.0, "init_high": -2.0}, r"init_low must be < init_high, got -1.0 and "
                                                r"-2.0$"),
        ({"init_low": [0.0, 1.0, 2.0], "init_high": [1.0, 2.0, 2.0]},
         r"init_low must be < init_high at coefficient 2, got \(0.0, 1.0, 2.0\)"),
        ({"init_high": 1e20}, r"init_high must be within \+-10000, got 1e\+20"),
        ({"init_low": [-1.0, -1e5, -1.0]}, r"init_low\[1\] must be within \+-10000"),
        ({"margin": 1e300}, r"margin must be within \+-100000 cm, got 1e\+300"),
        ({"certify_tol": 1e-300}, r"certify_tol must be 0 or at least 1.18e-38 cm"),
        ({"capacities": (10**9, 0, 4)}, r"capacities\[0\] must be <= 65536, got 1000000000"),
        ({"capacities": (1.5, 0, 4)}, r"capacities\[0\] must be an integer, got 1.5"),
        ({"capacities": 4}, r"capacities must be 3 slot counts .* got 4"),
        ({"joint_limits": [(-1e39, 1.0)] * 3}, r"joint_limits\[0\]\[0\] must be within"),
    ],
)
def test_bad_problem_fields_name_the_field_and_value(changes, message):
    fields = dict(arm=ARM, start=[0.0, 0.5, 0.5], goal=[1.0, 0.5, 0.5]) | changes
    with pytest.raises(ValueError, match=message):
        jaxarm.Problem(**fields)


@pytest.mark.parametrize(
    "lengths, message",
    [((30.0, -1.0), r"arm.lengths\[1\] must be > 0, got -1.0"),
     ((30.0, 0.0), r"arm.lengths\[1\] must be > 0, got 0.0"),
     ((), r"at least one link"),
     ((30.0, float("inf")), r"arm.lengths\[1\] must be finite, got inf"),
     ((1e300, 30.0), r"arm.lengths\[0\] must be within \+-100000 cm, got 1e\+300"),
     ((30.0, 1e-300), r"arm.lengths\[1\] must be 0 or at least 1.18e-38 cm")],
)
def test_bad_arm_lengths(lengths, message):
    with pytest.raises(ValueError, match=message):
        jaxarm.Arm(lengths)


def test_colliding_start_names_the_link_and_obstacle():
    world = jaxarm.World(circles=[(100.0, 100.0, 1.0)], boxes=[((25.0, -5.0), (35.0, 5.0))])
    with pytest.raises(ValueError, match=r"start posture .* collides: link 1 overlaps boxes\[0\]"):
        jaxarm.Problem(arm=ARM, start=[0.0, 1.5, 0.0], goal=[1.5, 0.5, 0.5], world=world)
    with pytest.raises(ValueError,
                       match=r"goal posture .* collides: link 3 overlaps circles\[0\]"):
        jaxarm.Problem(arm=ARM, start=[1.5, 0.5, 0.5], goal=[0.0, 0.0, 0.0],
                       world=jaxarm.World(circles=[(75.0, 0.0, 2.0)]))


def test_a_scenario_name_where_a_problem_goes_says_how_to_load_it():
    from jaxarm import plot

    calls = [lambda: jaxarm.solve("paper-case-2"),
             lambda: jaxarm.fitness("paper-case-2", [0, 0, 0]),
             lambda: jaxarm.certify("paper-case-2", [0, 0, 0]),
             lambda: jaxarm.escape_study("paper-case-2", ["A"], n_restarts=2),
             lambda: jaxarm.min_duration("paper-case-2", [0, 0, 0], max_velocity=1.0),
             lambda: plot.plot_motion("paper-case-2", [0, 0, 0])]
    for call in calls:
        with pytest.raises(ValueError, match=r"problem must be a jaxarm.Problem, got "
                                             r"'paper-case-2': load a scenario with "
                                             r"jaxarm.load_scenario\('paper-case-2'\)"):
            call()


def test_a_field_problem_has_not_is_named_with_the_nearest(case2):
    with pytest.raises(ValueError, match=r"Problem has no field 'samples'; did you mean "
                                         r"'n_samples'\?"):
        case2.replace(samples=101)
    with pytest.raises(jaxarm.ScenarioError, match=r"paper-case-2.toml: Problem has no field "
                                                   r"'colision'; did you mean 'collision'\?"):
        jaxarm.load_scenario("paper-case-2", colision="sampled")
    for not_a_name in (2, None):
        with pytest.raises(jaxarm.ScenarioError, match=r"scenario must be a shipped name or a "
                                                       rf"path to a .toml file, got {not_a_name}"):
            jaxarm.load_scenario(not_a_name)


def test_bad_parameters_are_rejected(case2):
    with pytest.raises(ValueError, match=r"x must have shape \(\.\.\., 3\).* got shape \(4,\)"):
        jaxarm.fitness(case2, np.zeros(4))
    with pytest.raises(ValueError, match=r"x must be finite"):
        jaxarm.fitness(case2, [0.0, float("nan"), 1.0])
    for not_numbers in ("abc", None, [[1.0, 2.0], [3.0]], [1j, 0.0, 0.0]):
        with pytest.raises(ValueError, match=r"x must be real numbers, shape \(\.\.\., 3\)"):
            jaxarm.certify(case2, not_numbers)


@pytest.mark.parametrize("mode", ["sampled", "certified"])
def test_an_empty_batch_gives_empty_answers(case2, mode):
    problem = case2.replace(collision=mode)
    empty = np.zeros((0, 3))
    for function in (jaxarm.fitness, jaxarm.violation, jaxarm.travelling_distance):
        assert np.asarray(function(problem, empty)).shape == (0,)
    assert np.asarray(jaxarm.certify(problem, empty).free).shape == (0,)
    # inside a caller's jit an empty batch is not padded: the kernels take it as it is
    assert jax.jit(lambda x: jaxarm.violation(problem, x))(empty).shape == (0,)


def test_joint_path_checks_the_order_and_the_times(case2):
    x = [66.7388, -28.1028, -9.8855]
    for order in (-1, 4, 1.5):
        with pytest.raises(ValueError, match=rf"order must be 0, 1, 2 or 3, got {order}"):
            jaxarm.joint_path(case2, x, [0.5], order=order)
    for r in ([-0.1, 0.5], [0.5, 1.2], [[0.5]], [float("nan")]):
        with pytest.raises(ValueError, match=r"r must be normalised times in \[0, 1\]"):
            jaxarm.joint_path(case2, x, r)
    assert jaxarm.joint_path(case2, x, [0.0, 1.0], order=3).shape == (2, 3)
    # one time, as a number: the path's angles there, without the times axis
    np.testing.assert_array_equal(jaxarm.joint_path(case2, x, 0.25),
                                  jaxarm.joint_path(case2, x, [0.25])[0])


def test_vmapped_evaluate_folds_the_mapped_axis_and_agrees(case2, rng):
    x = jnp.asarray(rng.uniform(-200, 200, (6, 5, 3)), jnp.float32)
    spec, arrays = case2.spec, case2.arrays
    direct = jaxarm.checks.evaluate.evaluate(spec, arrays, x)
    evaluate_spec = jaxarm.checks.evaluate.vmapped_evaluate(spec)
    mapped = jax.jit(jax.vmap(evaluate_spec, in_axes=(None, 0)))(arrays, x)
    for a, b in zip(direct, mapped):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # Mapping over problems with the same spec (only data differs) still works.
    smaller = case2.replace(world=jaxarm.World(circles=[(40.0, 4.5, 5.0)]))
    both = jax.tree.map(lambda a, b: np.stack([a, b]), case2.arrays, smaller.arrays)
    per_problem = jax.vmap(evaluate_spec)(both, x[:2])
    np.testing.assert_array_equal(np.asarray(per_problem.fitness[0]),
                                  np.asarray(direct.fitness[0]))
    np.testing.assert_array_equal(
        np.asarray(per_problem.fitness[1]),
        np.asarray(jaxarm.checks.evaluate.evaluate(spec, smaller.arrays, x[1]).fitness))


@pytest.mark.parametrize("mode", ["sampled", "certified"])
def test_overflowing_paths_are_never_feasible(case2, mode):
    # The public functions reject non-finite x; a swarm without a velocity clamp can still
    # drive positions to overflow inside a compiled search. (Case 2: the programs of the
    # reconstructed-obstacle test above.)
    problem = case2.replace(collision=mode)
    x = np.array([[np.inf, 0, 0], [1e30, 0, 0], [np.nan, 0, 0], [3e38, 3e38, -3e38]],
                 np.float32)
    # compiled, padded with 60 zero paths: the 64-row program the public functions run
    rows = np.concatenate([x, np.zeros((60, 3), np.float32)])
    evaluation, _ = jaxarm.checks.evaluate._evaluate_and_certify(problem.spec, problem.arrays, rows)
    assert np.all(np.asarray(evaluation.fitness[:4]) == 0)
    assert not np.any(np.asarray(evaluation.violation[:4]) == 0)


def test_share_capacities_gives_each_arm_its_largest_slots_and_one_search_program(case2):
    case1 = jaxarm.load_scenario("paper-case-1", collision="sampled")
    case2 = case2.replace(collision="sampled")
    trap = jaxarm.load_scenario("death-trap", collision="sampled")
    tunnel = jaxarm.load_scenario("four-link-tunnel", collision="sampled")
    shared = jaxarm.share_capacities([case1, case2, trap, tunnel])
    assert [p.name for p in shared] == [case1.name, case2.name, trap.name, tunnel.name]
    # (8, 0, 4), (1, 0, 4) and (0, 1, 4) give (8, 1, 4); the only 4-link arm keeps its own
    assert {p.capacities for p in shared[:3]} == {(8, 1, 4)}
    assert shared[3] is tunnel
    # Same verdicts, violations and fitness (to float32 rounding) at the padded capacities:
    # the paper's published paths (free and colliding) and random ones, near and far
    rng = np.random.default_rng(3)
    x = np.array([s.a6 for s in published.CASE_1 + published.CASE_2])
    x = np.concatenate([x, rng.normal(size=(64 - len(x), 3))
                        * rng.choice([1.0, 10.0, 100.0], size=(64 - len(x), 1))])
    for exact, padded in zip((case1, case2, trap), shared):
        verdicts = np.asarray(jaxarm.collides(exact, x))
        if exact is not trap:  # all 64 collide in death-trap; elsewhere both kinds are compared
            assert 0 < verdicts.sum() < len(x)
        np.testing.assert_array_equal(jaxarm.collides(padded, x), verdicts)
        np.testing.assert_allclose(jaxarm.violation(padded, x), jaxarm.violation(exact, x),
                                   rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(jaxarm.fitness(padded, x), jaxarm.fitness(exact, x),
                                   rtol=1e-6)
    # One compiled search serves every scene once their capacities are shared
    jaxarm.solve(shared[0], n_particles=8, n_iters=12, n_restarts=3)
    assert is_compiled(shared[2], jaxarm.PRESETS["A"], 8, 12, 3)
    assert not is_compiled(trap, jaxarm.PRESETS["A"], 8, 12, 3)
    with pytest.raises(ValueError, match=r"problems\[1\] must be a jaxarm.Problem"):
        jaxarm.share_capacities([case1, "death-trap"])


def test_problems_of_one_arm_share_the_posture_check_program():
    """Constructing a problem checks its start and goal in a compiled program; arms of as many
    joints and worlds of up to 4 circles and 4 polygons share it (lengths are data)."""
    from jaxarm.model import problem as problem_lib

    before = problem_lib._posture_depth.programs_made()
    for n_circles, lengths in ((1, (21.0, 22.0, 23.0)), (2, (31.0, 12.0, 13.0)), (3, ARM.lengths)):
        world = jaxarm.World(circles=[(200.0 + 10 * i, 0.0, 2.0) for i in range(n_circles)],
                             boxes=[((-90.0, 80.0), (-80.0, 90.0))] * (n_circles % 2))
        jaxarm.Problem(arm=jaxarm.Arm(lengths), start=[0.0, 0.5, 0.5], goal=[1.5, 0.5, 0.5],
                       world=world)
    assert problem_lib._posture_depth.programs_made() - before <= 1


@pytest.mark.parametrize("form", [list, tuple, np.asarray, jnp.asarray])
def test_public_functions_take_any_sequence_of_numbers(case2, form):
    """Lists, tuples, NumPy and JAX arrays give the same answers wherever a path is taken."""
    x = [66.7388, -28.1028, -9.8855]
    reference = np.asarray(x, np.float32)
    for function in (jaxarm.fitness, jaxarm.violation, jaxarm.travelling_distance,
                     jaxarm.coefficients):
        np.testing.assert_array_equal(function(case2, form(x)), function(case2, reference))
    np.testing.assert_array_equal(jaxarm.joint_path(case2, form(x), form([0.0, 0.5])),
                                  jaxarm.joint_path(case2, reference, np.array([0.0, 0.5])))
    np.testing.assert_allclose(jaxarm.raise_degree(form(x), 3, 8),  # keeps x's dtype
                               jaxarm.raise_degree(reference, 3, 8), rtol=1e-6)
    trajectory = jaxarm.Trajectory(case2, form(x), 2.0)  # in x's precision
    np.testing.assert_allclose(trajectory.at(form([0.0, 1.0])).position,
                               jaxarm.Trajectory(case2, reference, 2.0).at(
                                   np.array([0.0, 1.0])).position, rtol=1e-6)


@pytest.mark.parametrize("mode", ["sampled", "certified"])
def test_coefficients_that_overflow_float32_are_infinitely_colliding(case2, mode):
    """Finite coefficients of 1e15 and up overflow in the path: the check measured NaN, now
    violation +inf and fitness 0 (never free), and a certificate's clearance -inf."""
    problem = case2.replace(collision=mode)
    x = np.array([[1e15] * 3, [1e30] * 3, [66.7388, -28.1028, -9.8855]], np.float32)
    evaluation = jaxarm.evaluate(problem, x)
    np.testing.assert_array_equal(evaluation.violation[:2], np.inf)
    np.testing.assert_array_equal(evaluation.fitness[:2], 0.0)
    assert evaluation.violation[2] == 0 and evaluation.fitness[2] > 0  # the paper's free path
    if mode == "certified":
        certificate = jaxarm.certify(problem, x)
        assert not np.any(certificate.free[:2]) and np.all(certificate.colliding[:2])
        np.testing.assert_array_equal(certificate.clearance[:2], -np.inf)


@pytest.mark.parametrize("mode", ["sampled", "certified"])
def test_evaluate_is_fitness_violation_and_distance_in_one_pass(case2, rng, mode):
    problem = case2.replace(collision=mode)
    x = rng.uniform(-200, 200, (2, 40, 3)).astype(np.float32)
    x[:, :20] = np.float32([66.7388, -28.1028, -9.8855]) + rng.normal(0, 1, (2, 20, 3))
    evaluation = jaxarm.evaluate(problem, x)
    assert isinstance(evaluation, jaxarm.Evaluation)
    np.testing.assert_array_equal(evaluation.fitness, jaxarm.fitness(problem, x))
    np.testing.assert_array_equal(evaluation.violation, jaxarm.violation(problem, x))
    np.testing.assert_array_equal(evaluation.distance, jaxarm.travelling_distance(problem, x))
    assert 0 < np.sum(evaluation.violation > 0) < 80  # both kinds of path
    # inside a user's jit and vmap (an optimiser's loop over restarts): the same bits
    inside = jax.jit(jax.vmap(lambda rows: jaxarm.evaluate(problem, rows)))(x)
    for a, b in zip(evaluation, inside):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    with pytest.raises(ValueError, match=r"x must have shape \(\.\.\., 3\)"):
        jaxarm.evaluate(problem, np.zeros((4, 5)))
