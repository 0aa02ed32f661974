"""The certified continuous check (``jaxarm.checks.certified``, ``jaxarm.certify``) against an independent
dense oracle (shapely, float64)."""

import jax
import numpy as np
import pytest
from random_worlds import thin_wall_problem

import jaxarm
from jaxarm._compile.jit import jit
from jaxarm._compile.padding import SMALL_BATCH
from jaxarm.checks import certified
from jaxarm.checks.certified import bits, samples, windows
from jaxarm.checks.evaluate import _evaluate_and_certify
from jaxarm.paper import published
from jaxarm.paper.published import a6_array
from jaxarm.testing import dense_clearance, oracle_path_collides


@pytest.mark.slow
def test_certify_is_sound_and_tight_against_a_dense_oracle(rng):
    """0 false "free" over 300 random thin-obstacle worlds; motions clear by >= 2 tol are
    certified, motions penetrating by >= 2 tol are found colliding (the issue's targets)."""
    clearances, free, colliding = [], [], []
    for _ in range(300):
        problem = thin_wall_problem(rng)
        x = rng.uniform(-60, 60, (64, problem.n_free))
        sampled = np.asarray(jaxarm.violation(problem.replace(collision="sampled"), x)) == 0
        # Motions free at the 101 samples are the interesting ones; a few others too.
        rows = np.concatenate([np.nonzero(sampled)[0][:5], np.nonzero(~sampled)[0][:1]])
        certificate = jaxarm.certify(problem, x[rows])
        clearances.append(dense_clearance(problem, x[rows], 2001))
        free.append(np.asarray(certificate.free))
        colliding.append(np.asarray(certificate.colliding))
        assert not np.any(free[-1] & colliding[-1])
    clearance, free, colliding = map(np.concatenate, (clearances, free, colliding))
    tol = 0.01
    assert not np.any(free & (clearance < 0)), clearance[free & (clearance < 0)]
    clear = clearance >= 2 * tol
    deep = clearance <= -2 * tol
    assert clear.sum() > 500 and deep.sum() > 100, (clear.sum(), deep.sum())
    assert free[clear].mean() >= 0.995, free[clear].mean()
    assert colliding[deep].mean() >= 0.99, colliding[deep].mean()
    # The sampled check steps over some of these walls; the certified one must not.
    assert np.sum(deep & ~colliding) <= 0.01 * deep.sum()


def test_walls_of_zero_thickness_are_never_crossed_by_a_free_path(rng):
    """Segments at any angle: no path called free crosses one (or comes inside a circle) at
    any of 4,001 instants (shapely); the paths clear by 2 tol are certified."""
    clearances, free = [], []
    for _ in range(10):
        problem = thin_wall_problem(rng, wall="segment")
        x = rng.uniform(-60, 60, (64, problem.n_free))
        sampled = np.asarray(jaxarm.violation(problem.replace(collision="sampled"), x)) == 0
        rows = np.concatenate([np.nonzero(sampled)[0][:6], np.nonzero(~sampled)[0][:2]])
        certificate = jaxarm.certify(problem, x[rows])
        assert not np.any(np.asarray(certificate.free) & np.asarray(certificate.colliding))
        clearances.append(dense_clearance(problem, x[rows], 4001))
        free.append(np.asarray(certificate.free))
    clearance, free = map(np.concatenate, (clearances, free))
    assert not np.any(free & (clearance < 0)), clearance[free & (clearance < 0)]
    clear = clearance >= 0.02
    assert clear.sum() > 20 and free[clear].mean() >= 0.95, (clear.sum(), free[clear].mean())


@pytest.mark.parametrize("margin", [0.0, pytest.param(1.0, marks=pytest.mark.slow)])
def test_the_thin_wall_as_a_segment_is_solved_and_proved_to_the_edge(margin):
    """thin-wall rebuilt from a segment: the default search certifies a path, and the
    certified check holds on paths bisected from it to the edge of what it proves, towards a
    path through the wall (shapely, 20,001 instants)."""
    wall = jaxarm.load_scenario("thin-wall")
    (low, high), = wall.world.boxes
    middle = 0.5 * (low[1] + high[1])
    problem = wall.replace(world=jaxarm.World(segments=[((low[0], middle), (high[0], middle))]),
                           margin=margin)
    result = jaxarm.solve(problem, n_restarts=64, max_stages=2, progress=False)
    assert result.certified and jaxarm.certify(problem, result.best_x).free
    best = np.asarray(result.best_x, np.float64)
    others = np.random.default_rng(5).uniform(-150, 150, (64, problem.n_free))
    through = others[np.argmax(dense_clearance(problem, others, 2001) < 0)]  # crosses the wall
    assert dense_clearance(problem, through[None], 2001)[0] < 0
    inside, outside = 0.0, 1.0  # fractions of the way from best to through: free, not free
    for _ in range(24):
        middle = 0.5 * (inside + outside)
        x = (best + middle * (through - best)).astype(np.float32)
        if jaxarm.certify(problem, x).free:
            inside = middle
        else:
            outside = middle
    edge = (best + inside * (through - best)).astype(np.float32)
    assert jaxarm.certify(problem, edge).free
    assert dense_clearance(problem, edge[None], 20001)[0] >= margin - 1e-4


def test_certified_is_sound_and_not_too_conservative_against_a_dense_check(rng):
    certified_free = sampled_free = certified_of_dense_free = dense_free = 0
    missed_by_sampling = 0
    for _ in range(30):
        problem = thin_wall_problem(rng).replace(collision="sampled")
        certified = problem.replace(collision="certified")
        x = rng.uniform(-60, 60, (200, problem.n_free))
        sampled_ok = np.asarray(jaxarm.violation(problem, x)) == 0
        certified_ok = np.asarray(jaxarm.violation(certified, x)) == 0
        assert not np.any(certified_ok & ~sampled_ok)
        candidates = np.nonzero(sampled_ok)[0][:10]  # dense checks are the expensive part
        if candidates.size == 0:
            continue
        dense_ok = ~oracle_path_collides(problem, x[candidates], 10_001)
        # Soundness: nothing certified collides anywhere along the dense check.
        assert not np.any(certified_ok[candidates] & ~dense_ok)
        missed_by_sampling += np.sum(~dense_ok)
        certified_free += certified_ok.sum()
        sampled_free += sampled_ok.sum()
        dense_free += dense_ok.sum()
        certified_of_dense_free += np.sum(certified_ok[candidates] & dense_ok)
    assert missed_by_sampling > 0, "expected the sampled check to step over some thin walls"
    assert dense_free > 60
    # Not so conservative that it rejects most free motions.
    assert certified_of_dense_free / dense_free > 0.6, (certified_of_dense_free, dense_free)


def test_certificate_fields_and_the_papers_free_paths(case2):
    paths = np.array([published.CASE_2_TABLE_3[0].a6, published.CASE_2_TABLE_6[0][1]])
    certificate = jaxarm.certify(case2, paths)
    assert certificate.free.shape == (2,) and bool(np.all(certificate.free))
    assert not bool(np.any(certificate.colliding | certificate.exhausted))
    # A lower bound on the true clearance when free.
    assert np.all(np.asarray(certificate.clearance) <= dense_clearance(case2, paths) + 1e-4)
    assert np.all(np.asarray(certificate.clearance) >= 0)
    batched = jaxarm.certify(case2, np.broadcast_to(paths, (3, 2, 3)))
    assert batched.free.shape == (3, 2)


def test_colliding_motions_report_the_penetration_found(case1):
    x = np.array([[0.0, 0.0, 0.0], [80.0, -60.0, 10.0]])
    dense = dense_clearance(case1, x)
    assert dense_clearance(case1, x[:0]).shape == (0,)  # no paths (a search that never escaped)
    certificate = jaxarm.certify(case1, x)
    hits = dense < -0.1
    assert np.all(np.asarray(certificate.colliding)[hits])
    assert np.all(np.asarray(certificate.clearance)[hits] < 0)


def test_certified_verdicts_do_not_depend_on_the_batch(rng):
    """A path among others gets the verdict it gets among copies of itself (which is how a
    single path is checked: padded with copies). 200 paths, as in the dense check above, so
    that both run one compiled program."""
    for _ in range(20):  # a world where some of the paths collide and some do not
        problem = thin_wall_problem(rng)
        x = rng.uniform(-60, 60, (200, problem.n_free)).astype(np.float32)
        together = np.asarray(jaxarm.violation(problem, x))
        if np.sum(together > 0) >= 3 and np.sum(together == 0) >= 3:
            break
    picked = np.concatenate([np.nonzero(together == 0)[0][:3], np.nonzero(together > 0)[0][:3]])
    assert len(picked) == 6, together  # free paths and colliding ones
    alone = [np.asarray(jaxarm.violation(problem, np.repeat(x[[row]], len(x), 0)))[0]
             for row in picked]
    np.testing.assert_array_equal(together[picked], alone)


def test_small_certify_batches_share_one_program_and_agree_with_a_large_one(rng):
    problem = thin_wall_problem(rng)
    # 200 paths: the large batch runs the program of the next test's reference
    x = rng.uniform(-60, 60, (200, problem.n_free)).astype(np.float32)
    large = jaxarm.certify(problem, x)
    jaxarm.certify(problem, x[:1])
    programs = _evaluate_and_certify.programs_made()
    for size in (1, 5, SMALL_BATCH):
        small = jaxarm.certify(problem, x[:size])
        for name, field in small._asdict().items():
            assert field.shape == (size,)
            np.testing.assert_array_equal(field, getattr(large, name)[:size], err_msg=name)
    # fitness, violation and certify share one program per spec and batch size, whatever the
    # problem's collision mode
    violation = np.asarray(jaxarm.violation(problem, x))
    np.testing.assert_array_equal(violation == 0, large.free)
    sampled = jaxarm.certify(problem.replace(collision="sampled"), x[:5])
    np.testing.assert_array_equal(sampled.clearance, large.clearance[:5])
    assert _evaluate_and_certify.programs_made() == programs
    assert jaxarm.certify(problem, x[:0]).free.shape == (0,)


@pytest.mark.parametrize("scene", ["thin-wall", "paper-case-1"])
def test_window_chunks_and_lane_counts_do_not_change_verdicts(rng, scene):
    """The window pass over the paths without a witness at a sample, in chunks, and the
    bisection in either of its loops, give every path the same verdict as one chunk and the
    narrow loop. Thin-wall (a polygon) runs the screened pass, its random paths several chunks
    of its swing test and of its drift test; case 1 (circles) the dense pass, and its paths
    near the paper's need the bisection, more of them than the second loop has lanes."""
    if scene == "thin-wall":
        problem = thin_wall_problem(rng)
        x = rng.uniform(-10, 10, (200, problem.n_free)).astype(np.float32)
    else:
        problem = jaxarm.load_scenario(scene)
        near = a6_array(published.CASE_1)[rng.integers(0, len(published.CASE_1), 200)]
        x = (near + rng.normal(0.0, 0.3, near.shape)).astype(np.float32)
    arrays = problem.arrays
    # One chunk and one narrow loop: 200 paths (padded to 256) < the default window_chunk, at
    # most ``CheckSizes.narrow_limit()``: only the narrow loop is compiled (thin-wall: the one
    # program of the dense check and of the test above).
    one_chunk_narrow = jaxarm.certify(problem, x)._asdict()
    one_chunk_narrow["violation"] = jaxarm.violation(problem, x)
    for found_afterwards in ("witness_link", "witness_obstacle", "witness_other_link"):  # by
        # ``certify``, not the check
        del one_chunk_narrow[found_afterwards]
    lanes = 16
    sizes = certified.CheckSizes(window_chunk=16, swing_chunk=16, pair_chunk=16,
                                 lanes=lanes,  # the other loop, refilling its lanes
                                 few_paths=-1)  # always the other loop
    # compiled as ``certify`` is: the problem's arrays as arguments (as constants they were
    # folded into the program, and the clearances differed in their last bits)
    chunked_other = jit(lambda arrays, x: certified.check(problem.spec, arrays, x,
                                                          sizes=sizes))(arrays, x)
    assert np.sum(~one_chunk_narrow["colliding"]) > 3 * 16  # several chunks ran
    assert np.sum(one_chunk_narrow["free"]) > 10
    if scene == "paper-case-1":
        assert np.sum(np.asarray(chunked_other.pieces) > 0) > lanes
    for name, value in one_chunk_narrow.items():
        np.testing.assert_array_equal(value, np.asarray(getattr(chunked_other, name)),
                                      err_msg=name)


# The best path of a sampled search (preset A, 4 restarts, seed 0) in each scene.
NEAR_A_SOLUTION = {"polygon-field": [2.06, -27.84, -0.83], "narrow-gap": [35.45, -75.66, -9.94]}


@pytest.mark.parametrize("scene", sorted(NEAR_A_SOLUTION))
def test_screened_windows_fail_where_every_window_tested_fails(rng, scene):
    """The screened window pass (the swing screen, then the drift test on what it leaves)
    finds the failing windows that the drift test of every window finds, and its worst
    passed window is no better (the screen's bound is the looser). Paths about a solution,
    as a search's are, so that some windows pass the screen, some only the drift test and
    some neither."""
    problem = jaxarm.load_scenario(scene)
    spec, arrays = problem.spec, problem.arrays
    centre = np.asarray(NEAR_A_SOLUTION[scene])
    x = jax.numpy.asarray(centre + rng.normal(0.0, 1.0, (300, problem.n_free)), np.float32)
    motion = samples.Motion(arrays.lengths, arrays.world, arrays.start, arrays.goal, x)
    margin = np.float32(0.0)

    @jax.jit
    def both(x):
        clearances = samples.sample_clearances(
            arrays.lengths, arrays.world, arrays.start, arrays.goal, x, spec.degree,
            spec.n_samples)
        open_ = clearances.min(axis=0) >= 0
        moved = motion._replace(x=x)
        swing = windows.window_swings(
            arrays.lengths, arrays.start, arrays.goal, x,
            *windows.window_tables(spec.degree, spec.n_samples, x.dtype))
        screened_out = ((swing - clearances <= 0) & open_[None]).sum()
        sizes = certified.CheckSizes()
        return (windows.screened_window_pass(moved, clearances, open_, spec.degree,
                                             spec.n_samples, margin, sizes.swing_chunk,
                                             sizes.pair_chunk),
                windows.dense_window_pass(moved, *bits.rows_first(open_), spec.degree,
                                          spec.n_samples, margin, sizes.window_chunk),
                open_, screened_out)

    screened, dense, open_, screened_out = both(x)
    failing = np.unpackbits(np.asarray(dense.failing).view(np.uint8), axis=1,
                            bitorder="little").sum()
    open_windows = int(open_.sum()) * spec.n_samples
    assert 0 < failing and failing + int(screened_out) < open_windows  # all three kinds
    np.testing.assert_array_equal(np.asarray(screened.failing), np.asarray(dense.failing))
    assert np.all(np.asarray(screened.worst_passed) >= np.asarray(dense.worst_passed) - 1e-4)


def test_paths_not_to_prove_stop_at_the_samples(rng):
    """``check(..., prove)``: the paths to prove get the verdict they get without the mask;
    the others only stage 0's: colliding where a sample is, else neither free nor colliding,
    with violation inf (a search never keeps them: ``evaluate.ProofRequest``)."""
    problem = thin_wall_problem(rng)
    x = rng.uniform(-10, 10, (200, problem.n_free)).astype(np.float32)
    prove = rng.uniform(size=200) < 0.5
    check = jit(lambda arrays, x, prove: certified.check(problem.spec, arrays, x, prove))
    some = check(problem.arrays, x, prove)
    every = check(problem.arrays, x, np.ones(200, bool))
    at_a_sample = np.asarray(every.colliding) & (np.asarray(every.pieces) == 0)
    kept = prove | at_a_sample
    for name in certified.CertifiedCheck._fields:
        np.testing.assert_array_equal(np.asarray(getattr(some, name))[kept],
                                      np.asarray(getattr(every, name))[kept], err_msg=name)
    skipped = ~kept
    assert np.sum(skipped & np.asarray(every.free)) > 5  # some would have been proved free
    assert np.all(np.isinf(np.asarray(some.violation)[skipped]))
    assert not np.any(np.asarray(some.free)[skipped] | np.asarray(some.colliding)[skipped])
    assert np.all(np.asarray(some.pieces)[skipped] == 0)


def test_paths_whose_freedom_alone_matters_stop_at_their_first_open_piece(rng):
    """``check(..., free_only=...)``: the same free paths, with the same certificates; a path
    that is not free is still not free, with a positive violation, after no more pieces.
    Paths close around case 2's optimum, with a tolerance of 1 cm so that some end
    undecided."""
    problem = jaxarm.load_scenario("paper-case-2", certify_tol=1.0)
    optimum = np.array([66.7388, -28.1028, -9.8855], np.float32)
    x = (optimum + rng.normal(0.0, 0.5, (400, 3))).astype(np.float32)
    check = jit(lambda arrays, x, free_only: certified.check(
        problem.spec, arrays, x, np.ones(400, bool), free_only))
    every = check(problem.arrays, x, np.zeros(400, bool))
    early = check(problem.arrays, x, np.ones(400, bool))
    free = np.asarray(every.free)
    np.testing.assert_array_equal(np.asarray(early.free), free)
    for name in certified.CertifiedCheck._fields:
        np.testing.assert_array_equal(np.asarray(getattr(early, name))[free],
                                      np.asarray(getattr(every, name))[free], err_msg=name)
    assert np.all(np.asarray(early.violation)[~free] > 0)
    assert np.all(np.asarray(early.pieces) <= np.asarray(every.pieces))
    assert np.sum(np.asarray(early.pieces) < np.asarray(every.pieces)) >= 2


def test_margin_keeps_the_arm_away(case2):
    x = a6_array(published.CASE_2_TABLE_3 + published.CASE_2_TABLE_4[:1])
    dense = dense_clearance(case2, x)
    for margin in (0.05, 0.1):  # the start posture is 0.17 cm from the circle
        kept = dense >= margin + 0.02
        broken = dense < margin - 0.02
        for mode in ("sampled", "certified"):
            problem = case2.replace(margin=margin, collision=mode)
            free = np.asarray(jaxarm.violation(problem, x)) == 0
            assert not np.any(free & broken)
            if mode == "certified":
                assert np.all(free[kept])
                assert not np.any(np.asarray(jaxarm.certify(problem, x).free) & broken)


@pytest.mark.parametrize("field, value, message", [
    ("margin", -1.0, "margin must be >= 0"),
    ("margin", float("nan"), "margin must be finite"),
    ("margin", "wide", "margin must be a number"),
    ("certify_tol", 0.0, "certify_tol must be > 0"),
    ("certify_tol", float("inf"), "certify_tol must be finite"),
    ("certify_budget", 0, "certify_budget must be >= 1"),
    ("certify_budget", 2**27 + 1, "certify_budget must be <= 134217728, got 134217729"),
])
def test_bad_certification_settings_name_the_field(case2, field, value, message):
    with pytest.raises(ValueError, match=message):
        case2.replace(**{field: value})


def test_a_margin_the_start_posture_breaks_is_an_error(case2):
    with pytest.raises(ValueError, match="start posture .* breaks margin 40 cm"):
        case2.replace(margin=40.0)


def test_certified_is_the_default_and_sampled_results_say_so():
    """(A certified search: tests/test_search.py.)"""
    assert jaxarm.load_scenario("paper-case-1").collision == "certified"
    case2 = jaxarm.load_scenario("paper-case-2")
    assert case2.collision == "certified"
    sampled = jaxarm.solve(case2.replace(collision="sampled"), "A", n_restarts=2, n_particles=8,
                           n_iters=12, constraint="feasibility")
    assert sampled.feasible  # this seed's best path is free at the samples ...
    assert sampled.certified == bool(jaxarm.certify(case2, sampled.best_x).free)  # ... and here
    assert ("not certified" in sampled.summary()) == (not sampled.certified)
    # a sampled answer the certified check does not prove free says so
    assert "not certified" in sampled._replace(certified=False).summary()


def test_a_spare_keeps_the_proofs_that_far_beyond_the_margin(case2):
    """``check(..., spare)``: a path is proved free only with its bound ``spare`` beyond the
    margin, so what a spare proves the plain check proves too, and a search's evaluation (a
    bar given) asks for ``search_spare``. Paths around case 2's optimum, some within a
    few hundredths of a cm of an obstacle; a spare of 0.02 cm, below a tolerance of 0.05."""
    rng = np.random.default_rng(7)
    optimum = np.array([66.7388, -28.1028, -9.8855], np.float32)
    x = (optimum + rng.normal(0.0, 0.5, (200, 3))).astype(np.float32)
    tol, spare = 0.05, 0.02
    arrays = case2.replace(certify_tol=tol).arrays  # the same spec: the tolerance is an array
    check = jit(lambda arrays, x, spare: certified.check(case2.spec, arrays, x, spare=spare))
    plain, spared = check(arrays, x, 0.0), check(arrays, x, spare)
    free, free_spared = np.asarray(plain.free), np.asarray(spared.free)
    assert not np.any(free_spared & ~free)
    assert np.all(np.asarray(spared.clearance)[free_spared] >= spare)
    lost = free & ~free_spared
    assert lost.sum() >= 3 and free_spared.sum() >= 20, (lost.sum(), free_spared.sum())
    # undecided within the tolerance of the spare, not split until the budget runs out
    assert not np.any(np.asarray(spared.exhausted)[lost])
    assert np.all(np.asarray(plain.clearance)[lost] < spare + tol)
    # a search's evaluation: the same violations as the check with the search's spare
    spare = certified.search_spare(case2.arrays.lengths)
    assert 1e-5 < float(spare) < 1e-3
    no_bar = (np.full(200, -np.inf, np.float32), np.zeros(200, bool))
    searched = jit(lambda arrays, x: jaxarm.checks.evaluate.evaluate(case2.spec, arrays, x,
                                                                    no_bar))(case2.arrays, x)
    np.testing.assert_array_equal(np.asarray(searched.violation),
                                  np.asarray(check(case2.arrays, x, spare).violation))
