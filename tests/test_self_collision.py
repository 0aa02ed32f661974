"""Self-collision (``jaxarm.model.self_collision``): links that are not neighbours must not meet,
in both checks, against an independent oracle (shapely distances between the links)."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import shapely

import jaxarm
from jaxarm.checks.evaluate import deepest_contact
from jaxarm.model import self_collision
from jaxarm.model.arm import link_endpoints
from jaxarm.testing import dense_clearance, oracle_path_collides, self_clearance


def curling_chain(n_links: int, bend: float = 1.0) -> jaxarm.Problem:
    """An arm of 20 cm links that curls (``bend`` rad at each inner joint of its start),
    beside a wall: paths of its range cross its own links often."""
    bends = [bend] * (n_links - 2)
    return jaxarm.Problem(arm=jaxarm.Arm((20.0,) * n_links, self_collision=True),
                          start=[0.3, *bends, 0.5], goal=[1.2, *np.negative(bends), -0.5],
                          world=jaxarm.World(segments=[((40.0, -60.0), (90.0, -30.0))]),
                          init_low=-150.0, init_high=150.0)


def test_a_posture_whose_links_cross_is_refused(tmp_path):
    arm = jaxarm.Arm((30.0, 30.0, 20.0), self_collision=True)
    with pytest.raises(ValueError, match=r"goal posture \[0.0, 2.8, 2.8\] collides with itself: "
                                         r"links 1 and 3 cross \(by 2.576 cm\)"):
        jaxarm.Problem(arm=arm, start=[0.0, 0.5, 0.5], goal=[0.0, 2.8, 2.8])
    with pytest.raises(ValueError, match=r"start posture .* links 1 and 3 are 5.\d+ cm apart, "
                                         r"closer than margin 6 cm"):
        jaxarm.Problem(arm=arm, start=[0.0, 2.2, 2.2], goal=[0.0, 0.5, 0.5], margin=6.0)
    jaxarm.Problem(arm=jaxarm.Arm(arm.lengths), start=[0.0, 0.5, 0.5], goal=[0.0, 2.8, 2.8])
    path = tmp_path / "crossed.toml"
    path.write_text("[arm]\nlengths = [30.0, 30.0, 20.0]\nself_collision = true\n"
                    "[start]\njoints = [0.0, 0.5, 0.5]\n[goal]\njoints = [0.0, 2.8, 2.8]\n")
    with pytest.raises(jaxarm.ScenarioError, match="crossed.toml: goal posture .* collides with "
                                                  "itself"):
        jaxarm.load_scenario(path)
    path.write_text(path.read_text().replace("true", "'yes'"))
    with pytest.raises(jaxarm.ScenarioError, match="arm.self_collision must be true or false"):
        jaxarm.load_scenario(path)


# 11 links: 45 pairs, on an array axis at the samples; its start curls less, not to cross
@pytest.mark.parametrize("n_links, bend, margin", [
    (4, 1.0, 0.0), pytest.param(6, 1.0, 0.0, marks=pytest.mark.slow),
    pytest.param(6, 1.0, 1.0, marks=pytest.mark.slow),
    pytest.param(11, 0.3, 0.0, marks=pytest.mark.slow)])
def test_no_path_called_free_brings_two_links_closer_than_the_margin(rng, n_links, bend, margin):
    """Random paths of a curling chain: the certified check frees none whose links come
    within the margin of each other (or of the wall) at any of 20,001 instants, and finds
    colliding every one whose links cross at the oracle's 2,001."""
    problem = curling_chain(n_links, bend).replace(margin=margin)
    x = rng.uniform(-150, 150, (64, problem.n_free)).astype(np.float32)
    certificate = jaxarm.certify(problem, x)
    free, colliding = np.asarray(certificate.free), np.asarray(certificate.colliding)
    crossing = self_clearance(problem, x, 2001) < 0
    assert crossing.sum() >= 5 and free.sum() > 10, (crossing.sum(), free.sum())
    assert np.all(colliding[crossing])
    proved = x[free][:16]  # the dense oracle's 20,001 instants on a few of them
    closest = np.minimum(self_clearance(problem, proved, 20001),
                         dense_clearance(problem, proved, 20001))
    assert np.all(closest >= margin - 1e-4), closest.min()


@pytest.mark.parametrize("n_links, bend", [(6, 1.0), (11, 0.3)])  # 10 pairs written out; 45 not
def test_the_sampled_check_agrees_with_the_oracle_at_its_samples(n_links, bend, rng):
    problem = curling_chain(n_links, bend).replace(collision="sampled")
    x = rng.uniform(-150, 150, (200, problem.n_free)).astype(np.float32)
    ours = np.asarray(jaxarm.violation(problem, x))
    oracle = (self_clearance(problem, x, problem.n_samples) < 0) | oracle_path_collides(
        problem, x, problem.n_samples)
    decided = (ours == 0) | (ours > 1e-4)  # paths that only graze are left out
    assert decided.mean() > 0.95 and oracle.sum() > 20
    np.testing.assert_array_equal((ours > 0)[decided], oracle[decided])


def test_a_witness_names_the_two_links_and_the_violation_their_depth():
    problem = jaxarm.Problem(arm=jaxarm.Arm((30.0, 30.0, 20.0), self_collision=True),
                             start=[0.0, 0.5, 0.5], goal=[0.0, 2.3, 1.0])
    through = np.array([0.0, 300.0, 300.0], np.float32)  # the tip folds back over link 1
    certificate = jaxarm.certify(problem, through)
    assert bool(certificate.colliding) and int(certificate.witness_obstacle) == -1
    assert {int(certificate.witness_link), int(certificate.witness_other_link)} == {0, 2}
    sampled = problem.replace(collision="sampled")
    assert float(jaxarm.violation(sampled, through)) > 1.0  # cm: how deep they cross
    off = jaxarm.Problem(arm=jaxarm.Arm((30.0, 30.0, 20.0)), start=problem.start,
                         goal=problem.goal)
    assert bool(jaxarm.certify(off, through).free)  # without it, nothing stops them
    result = jaxarm.solve(problem.replace(init_low=-1.0, init_high=1.0), "A", n_restarts=4,
                          n_iters=2)
    assert result.feasible
    contact = deepest_contact(problem, through)  # what a result's summary and figures show
    assert int(contact.obstacle) == -1 and {int(contact.link), int(contact.other_link)} == {0, 2}


def test_the_five_link_detour_is_solved_with_self_collision_on():
    detour = jaxarm.load_scenario("five-link-detour")
    problem = detour.replace(arm=jaxarm.Arm(detour.arm.lengths, self_collision=True))
    result = jaxarm.solve(problem, n_restarts=32, max_stages=3, progress=False)
    assert result.certified
    x = np.asarray(result.best_x)[None]
    assert self_clearance(problem, x, 20001)[0] > 0 and dense_clearance(problem, x, 20001)[0] > 0


def test_a_postures_pairs_are_measured_as_shapely_measures_them(rng):
    """The host's pair separations (what refuses a start or goal): shapely's distance where
    two links are apart, negative exactly where they cross."""
    problem = curling_chain(6)
    checked = 0
    for _ in range(200):
        theta = rng.uniform(-2.8, 2.8, 6)
        ours = self_collision.posture_pair_separations(problem.arm.lengths, theta)
        links = _links(problem.arm.lengths, theta)
        for (i, j), value in zip(self_collision.pairs(6), ours):
            a, b = shapely.LineString(links[i]), shapely.LineString(links[j])
            if a.crosses(b):
                assert value < 0
            else:
                assert value == pytest.approx(a.distance(b), abs=1e-9)
            checked += 1
    assert checked == 2000


def test_many_pairs_on_an_array_axis_are_each_pair_written_out(rng, monkeypatch):
    """Past ``UNROLLED_PAIRS`` pairs the separations are computed on an array axis: the values
    of each pair written out (within 1e-4 cm: XLA rounds the two programs in their own ways),
    of the host's float64 measure, and under ``jax.vmap`` and ``jax.grad`` too. (A 7-link arm
    with the threshold lowered to 6 pairs: the 45 pairs of 11 links written out took 11 s
    to compile.)"""
    monkeypatch.setattr(self_collision, "UNROLLED_PAIRS", 6)
    lengths = np.array([20.0, 15.0, 10.0, 12.0, 8.0, 20.0, 15.0])
    checked = self_collision.pairs(len(lengths))
    assert len(checked) > self_collision.UNROLLED_PAIRS

    def on_an_axis(theta):
        return jnp.stack(self_collision.pair_separations(link_endpoints(lengths, theta)))

    def written_out(theta):
        links = link_endpoints(lengths, theta)
        return jnp.stack([self_collision.segment_separations(links[i], links[j])
                          for i, j in checked])

    theta = rng.uniform(-2.8, 2.8, (512, len(lengths))).astype(np.float32)
    together, apart = jax.jit(on_an_axis)(theta), jax.jit(written_out)(theta)
    np.testing.assert_allclose(np.asarray(together), np.asarray(apart), rtol=0, atol=1e-4)
    mapped = jax.jit(jax.vmap(on_an_axis))(theta[:8])  # (8, n_pairs)
    np.testing.assert_allclose(np.asarray(mapped).T, np.asarray(together)[:, :8], atol=1e-4)
    # the axis's gradient compiled; the pairs written out op by op (XLA compiles their
    # gradient for minutes)
    slopes = [run(jax.grad(lambda theta, f=f: jnp.sum(f(theta))))(theta[:8])
              for f, run in ((on_an_axis, jax.jit), (written_out, lambda f: f))]
    assert np.all(np.isfinite(np.asarray(slopes[0])))
    np.testing.assert_allclose(np.asarray(slopes[0]), np.asarray(slopes[1]), rtol=1e-3, atol=1e-3)
    host = np.stack([self_collision.posture_pair_separations(lengths, row) for row in theta], 1)
    assert np.abs(host).min() < 1.0 and (host < 0).any()  # near and crossing pairs among them
    np.testing.assert_allclose(np.asarray(together), host, rtol=0, atol=1e-3)


@pytest.mark.parametrize("n_links", [5, 11])  # 6 pairs written out; 45 on an array axis
def test_collinear_links_are_apart_by_their_gap_in_float32(n_links):
    """A straight chain turning, compiled on a batch: the sides of collinear links are rounding
    noise, which must not read as a crossing (shapely's distance)."""
    lengths = np.array([20.0, 15.0, 10.0, 12.0, 8.0, 20.0, 15.0, 10.0, 12.0, 8.0, 20.0][:n_links])
    turns = np.linspace(0.0, 1.0, 201, dtype=np.float32)
    separations = jax.jit(lambda turn: jnp.stack(self_collision.pair_separations(link_endpoints(
        jnp.asarray(lengths, jnp.float32), [turn] + [jnp.zeros_like(turn)] * (n_links - 1)))))(
        turns)
    for turn, ours in zip(turns, np.asarray(separations).T):
        links = _links(lengths, [float(turn)] + [0.0] * (n_links - 1))
        for (i, j), value in zip(self_collision.pairs(n_links), ours):
            a, b = shapely.LineString(links[i]), shapely.LineString(links[j])
            assert value == pytest.approx(a.distance(b), abs=1e-3), (turn, i, j)


def _links(lengths, theta):
    """Each link's end points, written out again (float64)."""
    points, angle = [(0.0, 0.0)], 0.0
    for length, turn in zip(lengths, theta):
        angle += turn
        x, y = points[-1]
        points.append((x + length * math.cos(angle), y + length * math.sin(angle)))
    return [(points[k], points[k + 1]) for k in range(len(lengths))]


@pytest.mark.parametrize("n_links", [5, 10, 20])
def test_the_kinematic_chain_scenes_are_ompls(n_links):
    """kinematic-chain-N as OMPL's demo builds it (demos/KinematicChainBenchmark.cpp), in cm:
    links of 100/N, start [0, pi/N, ...], goal [pi - 0.001, 0, ...], and the horn's two
    polylines of N - 1 walls from (100/N, -+100 eps), eps = ln(N)/N, the k-th along k pi/N, of
    signed lengths (100/N)(1 +- pi eps)."""
    problem = jaxarm.load_scenario(f"kinematic-chain-{n_links}")
    assert problem.arm.lengths == (100.0 / n_links,) * n_links and problem.arm.self_collision
    np.testing.assert_allclose(problem.start, [0.0] + [math.pi / n_links] * (n_links - 1))
    np.testing.assert_allclose(problem.goal, [math.pi - 0.001] + [0.0] * (n_links - 1))
    eps = math.log(n_links) / n_links
    walls = np.asarray(problem.world.segments)  # (2 (N - 1), 2, 2)
    assert walls.shape == (2 * (n_links - 1), 2, 2)
    for side, polyline in ((-1, walls[:n_links - 1]), (1, walls[n_links - 1:])):
        np.testing.assert_allclose(polyline[0, 0], [100.0 / n_links, side * 100 * eps])
        np.testing.assert_allclose(polyline[1:, 0], polyline[:-1, 1])  # joined end to end
        # the demo's signed length: for N = 5, 1 - pi eps < 0 and the upper walls run backwards
        turn = np.arange(1, n_links) * math.pi / n_links
        np.testing.assert_allclose(polyline[:, 1] - polyline[:, 0],
                                   100.0 / n_links * (1 - side * math.pi * eps)
                                   * np.stack([np.cos(turn), np.sin(turn)], axis=-1),
                                   rtol=1e-12, atol=1e-12)


def test_a_straight_chain_keeps_its_margin_from_itself():
    """At a straight posture every later link lies on an earlier one's line, apart from it:
    with a margin, the start and goal are accepted and a gentle path certified free."""
    problem = jaxarm.Problem(arm=jaxarm.Arm((20.0,) * 4, self_collision=True),
                             start=[0.0, 0.0, 0.0, 0.0], goal=[1.0, 0.0, 0.0, 0.0], margin=1.0)
    certificate = jaxarm.certify(problem, np.zeros(problem.n_free, np.float32))
    assert bool(certificate.free), certificate
    assert not bool(jaxarm.collides(problem.replace(collision="sampled"),
                                    np.zeros(problem.n_free, np.float32)))
    two = jaxarm.Problem(arm=jaxarm.Arm((20.0, 20.0), self_collision=True), start=[0.0, 0.0],
                         goal=[1.0, 2.0])  # no pair to meet
    assert two.arm.self_collision
