"""benchmarks/blocking.py: circles that block the paths better than the paper's, checked against
shapely and against the fitness and collision checks they bound."""

import numpy as np
import pytest

import jaxarm
from jaxarm.model import path
from jaxarm.paper import published
from jaxarm.paper.published import a6_array
from jaxarm.testing import dense_clearance, link_segments

shapely = pytest.importorskip("shapely")
import benchmark_modules  # noqa: E402  (tests/)

blocking = benchmark_modules.load("blocking")

# paper-case-1's three circles before the better paths were blocked
THREE_CIRCLES = ((46.0, 4.0, 10.44), (8.0, 2.0, 2.4), (32.0, 18.0, 2.79))


@pytest.fixture(scope="module")
def three_circles(case1):
    return case1.replace(world=jaxarm.World(circles=THREE_CIRCLES), capacities=None)


def test_nearest_distances_match_shapely(rng):
    a, b = rng.uniform(-50, 50, (40, 2)), rng.uniform(-50, 50, (40, 2))
    points = rng.uniform(-60, 60, (25, 2))
    lines = shapely.linestrings(np.stack([a, b], 1))
    expected = [shapely.distance(lines, shapely.Point(p)).min() for p in points]
    for exact, tolerance in ((False, 1e-4), (True, 1e-9)):
        ours = blocking.nearest_distances(points, (a, b), exact=exact, chunk=16)
        np.testing.assert_allclose(ours, expected, atol=tolerance)


def test_motion_segments_hold_every_link_at_every_time(case1):
    x = a6_array(published.CASE_1[:2])
    a, b = blocking.motion_segments(case1, x, 11)
    links = link_segments(case1, x, 11).reshape(-1, 2, 2)  # the independent kinematics
    found = np.concatenate([a, b], 1)  # (n_segments, 4)
    for segment in links.reshape(-1, 4):
        assert np.min(np.abs(found - segment).max(1)) < 1e-9


def test_a_kept_motion_does_not_leave_its_own_sweep_and_another_does(case1):
    keep = a6_array(published.CASE_1[:3])
    other = np.array([[20.0, -20.0, 40.0]])
    excursion, point = blocking.sweep_excursion(case1, np.concatenate([keep[:1], other]), keep,
                                                n_points=401, exact=True)
    assert excursion[0] < 1e-6
    assert excursion[1] > 1.0
    sweep = shapely.linestrings(link_segments(case1, keep, 2001).reshape(-1, 2, 2))
    # the point reported is that far from the kept sweep (measured here at 2,001 times)
    assert shapely.distance(sweep, shapely.Point(point[1])).min() == pytest.approx(
        excursion[1], abs=0.05)


def test_block_paths_blocks_them_and_keeps_the_kept_motions_a_gap_clear(three_circles):
    keep = a6_array(published.CASE_1)
    better = blocking.free_paths_above(three_circles, 0.185, [40, -70, -20], [60, -40, 20],
                                       step=2.0)
    assert len(better.x) >= 2 and np.all(better.fitness > 0.185)
    block = better.x[np.argsort(-better.fitness)[:6]]
    layout = blocking.block_paths(three_circles, keep, block, gap=0.05, max_obstacles=4,
                                  n_probe=6, tries=3)
    assert layout.blocked[-1] == len(block) == layout.n_block
    problem = blocking.with_circles(three_circles, layout.circles)
    assert bool(np.all(jaxarm.collides(problem, block)))
    assert not bool(np.any(jaxarm.collides(problem, keep)))
    added = problem.replace(world=jaxarm.World(circles=layout.circles))
    assert dense_clearance(added, keep).min() >= 0.05 - 1e-3  # the gap, by shapely


def test_the_proofs_bounds_hold_at_random_points_of_their_cubes(case1, rng):
    """``prove_blocked`` settles a cube by a fitness bound or a collision bound at its centre;
    every path drawn from a cube each bound settles must obey it."""
    import jax

    threshold, h = 0.175, 0.5
    centres = rng.uniform([30, -90, -40], [90, -40, 40], (400, 3))
    with jax.enable_x64(True):
        _, lipschitz = blocking._sample_bounds(case1)
        margin = np.asarray(blocking._depth_margin_fn(case1)(centres, np.full(len(centres), h)))
        distance = np.asarray(path.simpson_distance(
            np.asarray(case1.start), np.asarray(case1.goal), centres, case1.degree,
            case1.n_samples))
    low_fit = distance - lipschitz * h >= 1.0 / threshold
    hit = margin > 1e-9
    assert low_fit.sum() >= 20 and hit.sum() >= 20  # both bounds settle some cubes
    for settled, check in ((low_fit, lambda f: f <= threshold), (hit, lambda f: f == 0)):
        for centre in centres[settled][:40]:
            x = centre + rng.uniform(-h, h, (50, 3))
            assert np.all(check(np.asarray(jaxarm.fitness(case1, x), np.float64)))


def test_case_1_has_no_free_path_above_0_18_and_had_some_before(case1, three_circles):
    box = dict(low=[40, -70, -20], high=[64, -46, 24], step=1.0)
    assert len(blocking.free_paths_above(three_circles, 0.18, **box).x) > 0
    assert len(blocking.free_paths_above(case1, 0.18, **box).x) == 0
    proof = blocking.prove_blocked(case1, 0.18, [-128.0] * 3, [128.0] * 3, half_width=16.0,
                                   min_half_width=1 / 64)
    assert proof.proved and proof.meets_box and proof.by_collision > 0
    # around the best path the three circles left free (0.1904 at [49.4, -50.7, -3.2])
    before = blocking.prove_blocked(three_circles, 0.18, [44, -56, -8], [56, -44, 4],
                                    half_width=2.0, min_half_width=1 / 8)
    assert not before.proved
    # a box the better paths do not meet proves nothing, though all its cubes are settled
    far = blocking.prove_blocked(three_circles, 0.18, [128.0] * 3, [256.0] * 3, half_width=16.0)
    assert not far.proved and not far.meets_box and not len(far.unresolved)
    assert np.max(np.asarray(jaxarm.fitness(three_circles, before.unresolved))) > 0.18


def test_prove_blocked_refuses_boxes(case1):
    problem = case1.replace(world=jaxarm.World(boxes=[((60, 60), (70, 70))]), capacities=None)
    with pytest.raises(ValueError, match="circles only; 'paper-case-1' has 1 boxes"):
        blocking.prove_blocked(problem, 0.18, [-128.0] * 3, [128.0] * 3)
