"""Where a path collides (``jaxarm.certify``'s witness, ``jaxarm.collision_witness``) against an
independent oracle: shapely distances at the witness instant, float64 kinematics."""

import numpy as np
import pytest
import shapely

import jaxarm
from jaxarm.testing import link_segments_at, shapely_obstacles

# cm: float32 positions of an arm of 80 cm reach, and the float32 instant they are taken at.
TOLERANCE = 2e-3


def oracle_distances(problem, x, r) -> np.ndarray:
    """Shapely's distance (>= 0; 0 where they meet) of every link to every obstacle in
    ``World``'s order at each path's instant; shape (n_paths, n_joints, n_obstacles)."""
    segments = link_segments_at(problem, x, np.asarray(r, np.float64)[:, None])[:, 0]
    lines = shapely.linestrings(segments.reshape(-1, 2, 2))
    circles, polygons = shapely_obstacles(problem.world)
    columns = [np.maximum(shapely.distance(lines, center) - radius, 0.0)
               for center, radius in circles]
    columns += [shapely.distance(lines, polygon) for polygon in polygons]
    return np.stack(columns, axis=-1).reshape(len(x), problem.n_joints, -1)


def assert_witnesses_hold(problem, x, witness, colliding):
    """Every colliding path names an instant, a link and an obstacle where the oracle finds
    that link within the margin of that obstacle, and no pair nearer; the others name none."""
    r, link, obstacle = (np.asarray(a) for a in witness)
    assert np.all(np.isnan(r[~colliding])) and np.all(link[~colliding] == -1)
    assert np.all(obstacle[~colliding] == -1)
    rows = np.nonzero(colliding)[0]
    assert rows.size
    assert np.all((r[rows] >= 0) & (r[rows] <= 1))
    assert np.all((link[rows] >= 0) & (link[rows] < problem.n_joints))
    assert np.all((obstacle[rows] >= 0) & (obstacle[rows] < problem.world.n_obstacles))
    distances = oracle_distances(problem, x[rows], r[rows])
    named = distances[np.arange(rows.size), link[rows], obstacle[rows]]
    assert np.all(named <= problem.margin + TOLERANCE), named
    assert np.all(named <= distances.min(axis=(1, 2)) + TOLERANCE)


def random_paths(rng, problem, n_paths=64, spread=60.0):
    return rng.uniform(-spread, spread, (n_paths, problem.n_free)).astype(np.float32)


@pytest.mark.parametrize("scene, margin", [
    pytest.param("mixed-clutter", 0.0, marks=pytest.mark.slow), ("mixed-clutter", 1.5),
    pytest.param("polygon-field", 0.0, marks=pytest.mark.slow),
    pytest.param("clutter-100", 0.0, marks=pytest.mark.slow)])
def test_certify_names_where_each_colliding_path_collides(rng, scene, margin):
    problem = jaxarm.load_scenario(scene)
    problem = problem.replace(margin=margin) if margin else problem
    x = random_paths(rng, problem)
    certificate = jaxarm.certify(problem, x)
    colliding = np.asarray(certificate.colliding)
    assert_witnesses_hold(problem, x, (certificate.witness_r, certificate.witness_link,
                                       certificate.witness_obstacle), colliding)


def test_a_contact_between_samples_is_found_by_the_bisection(rng):
    """Few samples: paths the samples call free that collide between them get a witness at a
    time that is no sample, where the oracle finds the contact."""
    problem = jaxarm.load_scenario("thin-wall").replace(n_samples=11)
    x = random_paths(rng, problem, 256)
    certificate = jaxarm.certify(problem, x)
    sampled = np.asarray(jaxarm.violation(problem.replace(collision="sampled"), x))
    between = np.asarray(certificate.colliding) & (sampled == 0)
    assert between.sum() >= 3
    r = np.asarray(certificate.witness_r)[between]
    assert np.all(np.abs(r * 10 - np.round(r * 10)) > 1e-4)  # not one of the 11 samples
    witness = tuple(np.asarray(a)[between] for a in (certificate.witness_r,
                                                     certificate.witness_link,
                                                     certificate.witness_obstacle))
    assert_witnesses_hold(problem, x[between], witness, np.ones(between.sum(), bool))


@pytest.mark.parametrize("margin", [0.0, pytest.param(1.5, marks=pytest.mark.slow)])
def test_the_sampled_witness_is_the_deepest_sample(rng, margin):
    problem = jaxarm.load_scenario("mixed-clutter").replace(collision="sampled", margin=margin)
    x = random_paths(rng, problem)
    witness = jaxarm.collision_witness(problem, x)
    colliding = np.asarray(jaxarm.collides(problem, x))
    assert_witnesses_hold(problem, x, witness[:3], colliding)
    r = np.asarray(witness.r)[colliding]
    steps = r * (problem.n_samples - 1)
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-3)  # a sample
    assert np.all(np.asarray(witness.distance)[colliding] < margin)


def test_free_paths_have_no_witness_and_batches_keep_their_shape(case2):
    x = np.array([[66.7388, -28.1028, -9.8855], [0.0, 0.0, 0.0]])
    certificate = jaxarm.certify(case2, np.broadcast_to(x, (2, 2, 3)))
    assert certificate.witness_r.shape == certificate.witness_link.shape == (2, 2)
    assert np.isnan(np.asarray(certificate.witness_r)[:, 0]).all()
    assert (np.asarray(certificate.witness_obstacle)[:, 1] == 0).all()
    witness = jaxarm.collision_witness(case2, x[1])
    assert witness.r.shape == () and int(witness.link) == 1 and float(witness.distance) < 0


def test_plot_clearance_draws_each_links_distance_and_the_deepest_contact(case2):
    from jaxarm import plot

    problem = case2.replace(margin=0.5)
    figure = plot.plot_clearance(problem, [0.0, 0.0, 0.0], n_points=101)
    ax = figure.axes[0]
    labels = [line.get_label() for line in ax.get_lines()]
    assert [f"link {k}" for k in (1, 2, 3)] == labels[:3]
    assert "margin 0.5 cm" in labels and "witness: link 2" in labels
    distances = ax.get_lines()[1].get_ydata()
    assert distances.shape == (101,) and distances.min() < 0  # link 2 goes inside


def test_distances_along_a_path_are_shapelys_and_compile_once_for_a_summary_and_a_figure(
        rng, caplog):
    """``clearance_along`` (what a summary's deepest contact and the figures measure) against
    shapely at 201 and 401 instants: both counts run one compiled program, and its compiling
    is announced (a world of a shape no other test uses)."""
    import logging

    from jaxarm.checks.witness import clearance_along

    problem = jaxarm.clutter(jaxarm.load_scenario("five-link-detour"), 13, "triangles", seed=3)
    x = rng.uniform(*problem.bounds(), (problem.n_free,)).astype(np.float32)
    said = []
    for n_points in (201, 401):
        r = np.linspace(0.0, 1.0, n_points)
        with caplog.at_level(logging.INFO, logger="jaxarm.compile"):
            distance, obstacle, other = clearance_along(problem, x, r)
        said.append([record.getMessage() for record in caplog.records])
        caplog.clear()
        oracle = oracle_distances(problem, np.repeat(x[None], n_points, 0), r)
        assert distance.shape == obstacle.shape == (n_points, problem.n_joints)
        np.testing.assert_allclose(np.maximum(distance, 0.0), oracle.min(axis=-1),
                                   atol=TOLERANCE)
        picked = np.take_along_axis(oracle, obstacle[..., None], axis=-1)[..., 0]
        np.testing.assert_allclose(picked, oracle.min(axis=-1), atol=TOLERANCE)
        assert np.all(other == -1)  # this arm does not check self-collision
    assert any(m.startswith("compiling the distances along the path") for m in said[0]), said
    assert not said[1], said
