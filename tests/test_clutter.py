"""Random cluttered scenes (``jaxarm.clutter``, ``jaxarm clutter``): reproducible, the start and
goal kept clear, one-line errors, and solvable by the default search among hundreds."""

import numpy as np
import pytest
import shapely

import jaxarm
from jaxarm.cli import main
from jaxarm.testing import dense_clearance, shapely_obstacles


@pytest.fixture(scope="module")
def open_space():
    return jaxarm.load_scenario("open-space", margin=0.5)


@pytest.mark.parametrize("kind", ["circles", "triangles", "boxes"])
def test_the_same_seed_gives_the_same_world_and_keeps_the_postures_clear(open_space, kind):
    problem = jaxarm.clutter(open_space, 60, kind, size=(1.0, 4.0), seed=7)
    assert problem.world == jaxarm.clutter(open_space, 60, kind, size=(1.0, 4.0), seed=7).world
    assert problem.world != jaxarm.clutter(open_space, 60, kind, size=(1.0, 4.0), seed=8).world
    assert problem.world.n_obstacles == 60 and problem.name == f"open-space+60 {kind}"
    circles, polygons = shapely_obstacles(problem.world)
    shapes = [shapely.Point(c).buffer(r, 64) for c, r in circles] + polygons
    # every obstacle within the arm's reach, none within the margin of the start or goal
    assert max(shapely.distance(shapely.Point(0, 0), s) for s in shapes) < open_space.arm.reach
    at_the_ends = dense_clearance(problem, np.zeros((1, problem.n_free)), 2)  # r = 0 and 1
    assert at_the_ends[0] >= open_space.margin


def test_clutter_refuses_what_does_not_fit_and_bad_arguments(open_space):
    with pytest.raises(ValueError, match=r"cannot place 5 circles of size 200-300 cm clear"):
        jaxarm.clutter(open_space, 5, size=(200.0, 300.0))
    with pytest.raises(ValueError, match=r"kind must be one of"):
        jaxarm.clutter(open_space, 5, "hexagons")
    with pytest.raises(ValueError, match=r"size must be \(smallest, largest\)"):
        jaxarm.clutter(open_space, 5, size=(2.0, 1.0))
    with pytest.raises(ValueError, match=r"count must be >= 1"):
        jaxarm.clutter(open_space, 0)
    # a world holds MAX_SLOTS polygon slots: here 6 taken (5 boxes and a triangle)
    walled = open_space.replace(world=jaxarm.World(
        boxes=[((900.0, 900.0), (901.0, 901.0))] * 5,
        polygons=[[(950, 950), (951, 950), (950, 951)]]),
        capacities=None)
    for kind in ("boxes", "triangles"):
        with pytest.raises(ValueError, match=r"count must be <= 65530 \(a world holds 65536 "
                                             r"polygon slots and 'open-space' fills 6\), got "
                                             r"65531"):
            jaxarm.clutter(walled, 65_531, kind)
    with pytest.raises(ValueError, match=r"count must be <= 65536 .* got 70000"):
        jaxarm.clutter(walled, 70_000, "circles")  # its circle slots are all free
    with pytest.raises(ValueError, match=r"clear_path must have 3 values, got 2"):
        jaxarm.clutter(open_space, 5, clear_path=[1.0, 2.0])
    with pytest.raises(ValueError, match=r"clear_path must be a sequence of numbers, got 'no'"):
        jaxarm.clutter(open_space, 5, clear_path="no")
    for scalar in (False, 0.5):  # a scalar stands for zeros only as 0
        with pytest.raises(ValueError, match=r"clear_path must be 0 \(the path with no free "
                                             r"coefficients\) or 3 numbers, got " + str(scalar)):
            jaxarm.clutter(open_space, 5, clear_path=scalar)


def test_the_command_writes_a_scenario_that_loads_back(tmp_path, capsys):
    out = tmp_path / "clutter.toml"
    assert main(["clutter", "open-space", "--count", "40", "--kind", "boxes", "--size", "1",
                 "2", "--seed", "3", "-o", str(out), "--quiet"]) == 0
    assert "40 boxes" in capsys.readouterr().out
    loaded = jaxarm.load_scenario(out)
    made = jaxarm.clutter(jaxarm.load_scenario("open-space"), 40, "boxes", (1.0, 2.0), seed=3)
    assert loaded.world == made.world
    assert main(["clutter", "open-space", "--count", "4", "--size", "3", "1", "-o",
                 str(out)]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1].startswith("jaxarm: error: --size")
    missing = tmp_path / "no-such-folder" / "clutter.toml"  # named, not a temporary file
    assert main(["clutter", "open-space", "--count", "4", "-o", str(missing)]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"jaxarm: error: --output {str(missing)!r}: folder {str(missing.parent)!r} does not "
        "exist")


@pytest.mark.parametrize("count, kind, size", [(300, "circles", (0.3, 1.2)),
                                               (250, "triangles", (0.4, 1.5))])
def test_the_default_search_finds_a_certified_path_among_hundreds(count, kind, size):
    problem = jaxarm.clutter(jaxarm.load_scenario("open-space"), count, kind, size, seed=0,
                             clear_path=0)
    result = jaxarm.solve(problem, n_restarts=4)
    assert result.certified
    assert dense_clearance(problem, np.asarray(result.best_x)[None], 20_001, cutoff=5.0)[0] >= 0


def test_the_scene_scale_benchmark_times_a_search(monkeypatch):
    """``benchmarks/scene_scale.py --search``'s row (a few paths, the smallest scene): the
    search's columns say how many of the restarts run escaped and whether its path is
    certified."""
    from benchmark_modules import load

    scene_scale = load("scene_scale")
    monkeypatch.setattr(scene_scale, "PATHS", 64)
    row = scene_scale.measure("circles", 4, "sampled", search=True, before=False)
    assert row["obstacles"] == 4 and row["paths_per_s"] > 0
    assert 1 <= row["restarts"] <= 50 and 1 <= row["escapes"] <= row["restarts"]
    assert isinstance(row["certified"], bool) and row["search_warm"] > 0  # JSON for the parent
