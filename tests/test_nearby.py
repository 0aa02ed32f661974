"""The broad phase (``jaxarm.model.nearby``): sound lists, the same verdicts as testing every
slot, no false "free" against the dense shapely oracle among hundreds of obstacles, and a
program that does not grow with the obstacles."""

import pickle
import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import shapely

import jaxarm
from jaxarm.checks import certified, collision
from jaxarm.checks.evaluate import evaluate
from jaxarm.model import nearby
from jaxarm.model.arm import link_endpoints
from jaxarm.model.world import POLYGON_FIELDS
from jaxarm.testing import dense_clearance, oracle_separation, shapely_obstacles

ARM = jaxarm.Arm((30.0, 30.0, 20.0))


def corridor_world(rng, count: int, kind: str) -> jaxarm.World:
    """``count`` small obstacles within reach, none in the sector the arm moves through (from
    angle -0.35 to 0.85 rad), so that random slow paths are a mix of free and colliding."""
    placed = []
    while len(placed) < count:
        x, y = rng.uniform(-85, 85, 2)
        if 10 < np.hypot(x, y) < 85 and not -0.35 < np.arctan2(y, x) < 0.85:
            placed.append((x, y, rng.uniform(0.3, 1.5)))
    if kind == "circles":
        return jaxarm.World(circles=placed)
    return jaxarm.World(polygons=[[(x - r, y - r), (x + r, y - r), (x, y + r)]
                                  for x, y, r in placed])


def link_at(rng, before, length: float, direction):
    """End points (start, end), each of shape (n, 2), of a link of ``length`` pointing along
    ``direction`` (rad, shape (n,)), at the end of a chain of links of lengths ``before``
    from the origin at random angles (float64)."""
    angles = rng.uniform(0, 2 * np.pi, (len(direction), len(before)))
    start = np.stack([np.cos(angles), np.sin(angles)], -1).transpose(0, 2, 1) @ np.asarray(
        before, np.float64) if len(before) else np.zeros((len(direction), 2))
    return start, start + length * np.stack([np.cos(direction), np.sin(direction)], -1)


def corridor_problem(rng, count, kind, collision="certified", margin=0.0, world=None):
    """A problem among ``corridor_world``'s obstacles (or ``world``'s)."""
    world = corridor_world(rng, count, kind) if world is None else world
    return jaxarm.Problem(arm=ARM, start=[0.0, 0.0, 0.0], goal=[0.5, 0.0, 0.0],
                          world=world, collision=collision,
                          margin=margin, init_low=-60.0, init_high=60.0)


def without_tables(problem):
    """The problem's arrays with every slot tested (the broad phase off)."""
    arrays = problem.arrays
    return arrays._replace(world=arrays.world._replace(near=None))


def test_small_worlds_have_no_tables_and_large_ones_do(rng):
    assert jaxarm.load_scenario("mixed-clutter").arrays.world.near is None
    problem = corridor_problem(rng, nearby.BROAD_PHASE_WORK + 1, "circles")
    tables = problem.arrays.world.near
    assert tables is not None and tables.circle_lists.shape[-1] % nearby.BLOCK == 0
    assert tables.circle_lists.shape[:2] == (ARM.n_joints, nearby.DIRECTION_BINS)


def test_a_few_dozen_polygons_get_one_list_of_every_slot_and_more_get_the_grid(rng):
    problem = corridor_problem(rng, 40, "triangles")  # 120 polygon edges
    assert nearby.reads_every_slot(problem.capacities)
    tables = problem.arrays.world.near
    assert nearby.lists_every_slot(tables) and float(tables.reach) == np.inf
    lists = tables.polygon_lists.reshape(ARM.n_joints, -1)
    block = nearby.POLYGON_BLOCK["certified"]
    assert lists.shape[1] == 40 and np.all(lists == np.arange(40))
    assert np.all(tables.polygon_blocks == 40 // block)
    for row in range(40 // block):  # block b's row holds slots b * block ... in order
        np.testing.assert_array_equal(
            tables.polygons[0][tables.polygon_rows[row * ARM.n_joints]],
            problem.arrays.world.vertices[row * block:(row + 1) * block].astype(np.float32))
    for count, kind in ((200, "triangles"), (nearby.BROAD_PHASE_WORK + 1, "circles")):
        problem = corridor_problem(rng, count, kind)
        assert not nearby.reads_every_slot(problem.capacities)
        assert not nearby.lists_every_slot(problem.arrays.world.near)


def test_a_links_direction_bin_is_that_of_its_angle(rng):
    """``direction_bin`` (cross products) against numpy's ``arctan2`` modulo pi, for
    directions away from the bins' edges (there either bin is sound), of every length."""
    n_bins = nearby.DIRECTION_BINS
    angle = rng.uniform(-np.pi, np.pi, 20_000)
    within = np.mod(angle, np.pi / n_bins) / (np.pi / n_bins)
    angle = angle[(within > 1e-4) & (within < 1 - 1e-4)]
    length = 10.0 ** rng.uniform(-3, 2, angle.shape)
    dx, dy = (length * np.cos(angle)).astype(np.float32), (length * np.sin(angle)).astype(
        np.float32)
    expected = np.floor(np.mod(angle, np.pi) / (np.pi / n_bins)).astype(np.int32)
    found = np.asarray(nearby.direction_bin(jnp.asarray(dx), jnp.asarray(dy), n_bins))
    np.testing.assert_array_equal(found, expected)
    assert set(np.unique(found)) == set(range(n_bins))
    zero = nearby.direction_bin(jnp.zeros(2), jnp.array([0.0, jnp.nan]), n_bins)
    np.testing.assert_array_equal(zero, [0, 0])


@pytest.mark.parametrize("count, collision, largest_kept", [
    (nearby.BROAD_PHASE_WORK + 1, "certified", True), (1000, "certified", False),
    (nearby.BROAD_PHASE_WORK + 1, "sampled", True), (2000, "sampled", False)])
def test_the_tables_take_the_largest_reach_whose_lists_are_shortest(
        rng, count, collision, largest_kept):
    """Among a check's candidate reaches, the tables keep the largest whose lists are no
    longer (in whole blocks) than the smallest reach's: just past the threshold every
    candidate lists as few blocks, and the largest is kept; among 1,000 circles (2,000 for the
    sampled check's two candidates) the largest lists more, and a shorter one is kept. The
    chosen tables are those built for that reach alone."""
    problem = corridor_problem(rng, count, "circles", collision=collision, margin=0.5)
    packed, tables = problem.world.pack(problem.capacities), problem.arrays.world.near
    candidates = nearby.reach_candidates(ARM.lengths, 0.5, certified=collision == "certified")
    assert len(candidates) > 1
    blocks = {reach: nearby.build(packed, ARM.lengths, reach, collision).circle_lists.shape[-1]
              for reach in candidates}
    chosen = float(tables.reach)
    assert chosen in candidates and (chosen == max(candidates)) == largest_kept
    assert blocks[chosen] == blocks[min(candidates)]
    assert all(blocks[reach] > blocks[chosen] for reach in candidates if reach > chosen)
    alone = nearby.build(packed, ARM.lengths, chosen, collision)
    np.testing.assert_array_equal(alone.circle_lists, tables.circle_lists)
    np.testing.assert_array_equal(alone.circle_rows, tables.circle_rows)


def test_a_circle_lists_padding_is_beyond_the_reach_of_every_link(rng):
    """Circle blocks carry no valid flags (``nearby.LISTED_FIELDS``): a list's padding is a
    circle whose separation from every segment within the arm's reach (where every link is)
    exceeds the tables' reach by more than the arm's length, so a depth or a clearance bound
    taken from it is that of no obstacle. Checked on the padded slots of every row, with
    shapely."""
    tables = corridor_problem(rng, 300, "circles").arrays.world.near
    (numbers,) = tables.circles
    slots = tables.circle_lists.reshape(-1, tables.circle_lists.shape[-1])
    assert (slots == 300).any()  # some padding
    padding = np.unique(numbers[numbers[..., 2] == 0.0], axis=0)
    assert len(padding) == 1
    (x, y, radius), reach = padding[0].astype(np.float64), float(tables.reach)
    arm_disc = shapely.Point(0.0, 0.0).buffer(ARM.reach, 256)
    assert shapely.distance(arm_disc, shapely.Point(x, y)) - radius > reach + ARM.reach


@pytest.mark.parametrize("kind, collision", [("circles", "certified"),
                                             ("triangles", "certified"),
                                             ("triangles", "sampled")])
def test_every_obstacle_within_reach_of_a_link_is_listed(rng, kind, collision):
    """Each link at random postures of the arm, in every direction (some on the bins' edges):
    every obstacle closer than the tables' reach (shapely) is in the list ``near_cells``
    picks, and the list's rows hold that obstacle's numbers (in the polygon blocks of each
    check's size)."""
    problem = corridor_problem(rng, 300, kind, collision=collision)
    world, tables = problem.arrays.world, problem.arrays.world.near
    reach = float(tables.reach)
    circles, polygons = shapely_obstacles(problem.world)
    shapes = ([shapely.Point(c).buffer(r, 256) for c, r in circles] + polygons)
    if kind == "circles":
        n_slots, lists, rows, numbers = (len(circles), tables.circle_lists, tables.circle_rows,
                                         tables.circles)
        own = [getattr(world, name) for name in nearby.LISTED_FIELDS["circle"]]
    else:
        n_slots, lists, rows, numbers = (len(polygons), tables.polygon_lists,
                                         tables.polygon_rows, tables.polygons)
        own = [getattr(world, name) for name in nearby.LISTED_FIELDS["polygon"]]
    lists = lists.reshape(-1, lists.shape[-1])
    block = numbers[0].shape[1]
    assert block == (nearby.BLOCK if kind == "circles" else nearby.POLYGON_BLOCK[collision])
    edges = np.arange(2 * nearby.DIRECTION_BINS) * np.pi / nearby.DIRECTION_BINS
    for link, length in enumerate(ARM.lengths):
        angle = np.concatenate([rng.uniform(0, 2 * np.pi, 368),
                                edges + rng.choice([-1e-6, 1e-6], len(edges))])
        start, end = link_at(rng, ARM.lengths[:link], length, angle)
        start, end = start.astype(np.float32), end.astype(np.float32)
        lines = shapely.linestrings(np.stack([start, end], 1).astype(np.float64))
        listed_in = np.asarray(nearby.near_cells(tables, link, start[:, 0], start[:, 1],
                                                 end[:, 0], end[:, 1]))
        for index, shape in enumerate(shapes):
            for k in np.nonzero(shapely.distance(lines, shape) <= reach)[0]:
                slots = lists[listed_in[k]]
                assert index in slots[slots < n_slots], (link, index, k)
                position = int(np.nonzero(slots == index)[0][0])
                row = rows[(position // block) * lists.shape[0] + listed_in[k]]
                for listed_field, own_field in zip(numbers, own):  # every field of the slot
                    np.testing.assert_array_equal(listed_field[row, position % block],
                                                  own_field[index].astype(listed_field.dtype))


@pytest.mark.parametrize("kind, collision", [("circles", "certified"), ("triangles", "sampled")])
def test_a_lists_blocks_past_its_count_are_padding(rng, kind, collision):
    """``circle_blocks`` / ``polygon_blocks``: a list's listed slots fill its first blocks, and
    every block past them is padding; lists differ in length."""
    problem = corridor_problem(rng, 300, kind, collision=collision)
    world, tables = problem.arrays.world, problem.arrays.world.near
    if kind == "circles":
        lists, used, n_slots = tables.circle_lists, tables.circle_blocks, len(world.circles)
    else:
        lists, used, n_slots = tables.polygon_lists, tables.polygon_blocks, len(world.vertices)
    block = nearby.BLOCK if kind == "circles" else nearby.POLYGON_BLOCK[collision]
    lists = lists.reshape(-1, lists.shape[-1] // block, block)
    holds_a_slot = (lists < n_slots).any(axis=-1)  # (M, blocks)
    np.testing.assert_array_equal(holds_a_slot,
                                  np.arange(lists.shape[1])[None] < used[:, None])
    assert used.max() == lists.shape[1] and np.mean(used < used.max()) > 0.5


@pytest.mark.parametrize("kind", ["triangles", "circles"])
def test_a_block_few_links_reach_is_read_by_those_alone(rng, monkeypatch, kind):
    """``over_blocks`` with chunks of 16 links: a block that at most ``SPARSE_SHARE`` of the
    links' lists reach is read by those links alone, any other by every link (circles too,
    where ``GATHERED`` names them); with the default chunk, this batch is too small to gather
    links, and every link reads every block some list reaches."""
    problem = corridor_problem(rng, 300, kind, collision="sampled")
    tables = problem.arrays.world.near
    link = rng.integers(0, ARM.n_joints, 1000)
    ends = rng.uniform(-40, 40, (4, 1000)).astype(np.float32)
    cells = np.asarray(nearby.near_cells(tables, link, *ends))
    if kind == "circles":
        used, block, field = tables.circle_blocks[cells], nearby.BLOCK, "circles"
        n_blocks = tables.circle_lists.shape[-1] // block
    else:
        used, block, field = (tables.polygon_blocks[cells], nearby.POLYGON_BLOCK["sampled"],
                              "vertices")
        n_blocks = tables.polygon_lists.shape[-1] // block
    share = np.array([np.mean(used > b) for b in range(n_blocks)])
    assert np.any((share > 0) & (share <= nearby.SPARSE_SHARE)) and share[0] > 0.5

    def reads(cells=cells):  # how many blocks each link read
        return np.asarray(jax.jit(lambda cells: nearby.over_blocks(
            tables, cells, lambda world, _: jnp.ones(getattr(world, field).shape[-1]),
            "add"))(cells))
    np.testing.assert_array_equal(reads(), np.sum(share > 0))
    monkeypatch.setattr(nearby, "CHUNK", 16)
    monkeypatch.setattr(nearby, "GATHERED", ("circle", "polygon"))
    alone = share <= nearby.SPARSE_SHARE
    expected = np.sum(np.where(alone[None], used[:, None] > np.arange(n_blocks), share > 0), 1)
    np.testing.assert_array_equal(reads(), expected)
    assert reads(np.zeros(0, np.int32)).shape == (0,)  # no links: every block skipped


# The certified cases compile two certified checks each: in the full suite alone (``slow``).
@pytest.mark.parametrize("kind, collision", [
    ("triangles", "sampled"), pytest.param("triangles", "certified", marks=pytest.mark.slow),
    pytest.param("circles", "certified", marks=pytest.mark.slow)])
def test_links_that_read_a_block_alone_get_the_bits_of_every_link_reading_it(
        rng, monkeypatch, kind, collision):
    """Chunks of 16 links (the blocks few lists reach read by those links alone; circles too,
    where ``GATHERED`` names them) give every field of ``evaluate`` bit for bit as this batch
    gives with the default chunk (every link reading every block)."""
    problem = corridor_problem(rng, 300, kind, collision=collision, margin=0.25)
    x = rng.uniform(-60, 60, (200, problem.n_free)).astype(np.float32)

    def run():  # traced anew: the chunk is read when tracing
        return jax.jit(lambda arrays, x: evaluate(problem.spec, arrays, x))(problem.arrays, x)
    every = run()
    monkeypatch.setattr(nearby, "CHUNK", 16)
    monkeypatch.setattr(nearby, "GATHERED", ("circle", "polygon"))
    alone = run()
    for field in every._fields:
        np.testing.assert_array_equal(getattr(alone, field), getattr(every, field))
    assert 0.1 < np.mean(np.asarray(every.fitness) > 0) < 0.9
    # and the gathered blocks were read: with their values dropped, the check changes
    monkeypatch.setattr(nearby, "_combined_at", lambda result, at, values, combine: result)
    assert not np.array_equal(run().violation, every.violation)


def test_refines_gradient_passes_through_gathered_blocks(rng, monkeypatch):
    """Reverse-mode gradients of the links' clearances (``refine``'s barrier, through each
    link's nearest listed slot) where blocks are read by a few links alone are those of every
    link reading every block."""
    problem = corridor_problem(rng, 300, "triangles")
    world = problem.arrays.world
    theta = [jnp.asarray(rng.uniform(-3, 3, 300), jnp.float32) for _ in range(ARM.n_joints)]

    def clearance(theta):  # near obstacles only: a clearance capped at 3 cm
        return sum(jnp.sum(jnp.minimum(bound, 3.0)) for bound in collision.link_clearance_bounds(
            ARM.lengths, world, link_endpoints(ARM.lengths, theta), exact=False,
            by_nearest=True))
    every = jax.grad(clearance)(theta)
    monkeypatch.setattr(nearby, "CHUNK", 16)
    alone = jax.grad(clearance)(theta)
    for joint in range(ARM.n_joints):
        np.testing.assert_array_equal(alone[joint], every[joint])
    assert np.abs(np.asarray(every[0])).sum() > 0


def mixed_problem(rng, collision="certified"):
    """``corridor_problem`` among 100 circles and 100 triangles (the grid's tables)."""
    circles, triangles = (corridor_world(rng, 100, kind) for kind in ("circles", "triangles"))
    return corridor_problem(rng, 0, "", collision, world=jaxarm.World(
        circles=circles.circles, polygons=triangles.polygons))


@pytest.mark.parametrize("kind, count", [  # 40: one list of every slot
    ("circles", 300), pytest.param("triangles", 300, marks=pytest.mark.slow),
    pytest.param("mixed", 200, marks=pytest.mark.slow), ("triangles", 40)])
def test_the_nearest_listed_slot_is_the_nearest_obstacle_for_shapely(rng, monkeypatch, kind,
                                                                     count):
    """``over_blocks``' "nearest" of exact separations: where a link's nearest obstacle lies
    outside it within the tables' reach, the slot it names holds that obstacle (shapely's
    distance from the slot's own numbers is shapely's nearest distance of every obstacle) and
    its value is that distance. Of the separating-axis bounds (refine's), the same bits
    whether a block is read by every link or by the few links that need it."""
    # Small blocks: lists of several blocks, the later ones read by few links (gathered).
    monkeypatch.setattr(nearby, "BLOCK", 4)
    monkeypatch.setattr(nearby, "POLYGON_BLOCK", {"sampled": 2, "certified": 2})
    problem = mixed_problem(rng) if kind == "mixed" else corridor_problem(rng, count, kind)
    tables = problem.arrays.world.near
    theta = [jnp.asarray(rng.uniform(-3, 3, 400), jnp.float32) for _ in range(ARM.n_joints)]
    links = link_endpoints(ARM.lengths, theta)

    def nearest(index, exact):  # traced anew: the chunk is read when tracing
        return jax.jit(lambda link: nearby.over_blocks(
            tables, nearby.near_cells(tables, index, *link),
            lambda block, link: collision.first_smallest(
                collision.slot_separations(link, block, exact=exact)),
            "nearest", link))(links[index])
    every = [nearest(index, False) for index in range(ARM.n_joints)]
    exact = [nearest(index, True) for index in range(ARM.n_joints)]
    monkeypatch.setattr(nearby, "CHUNK", 16)
    monkeypatch.setattr(nearby, "GATHERED", nearby.KINDS)
    for index in range(ARM.n_joints):
        alone = nearest(index, False)
        for field in alone._fields:
            np.testing.assert_array_equal(getattr(alone, field), getattr(every[index], field))
    if not nearby.lists_every_slot(tables):  # and the gathered blocks were read
        monkeypatch.setattr(nearby, "_combined_at", lambda result, at, values, combine: result)
        assert any(not np.array_equal(nearest(index, False).value, every[index].value)
                   for index in range(ARM.n_joints))
    reach, near = float(tables.reach), 0
    for link, found in zip(links, exact):
        start, end = (np.stack([np.asarray(a, np.float64) for a in pair], -1)
                      for pair in (link[:2], link[2:]))
        oracle, _ = oracle_separation(problem.world, start, end)
        within = (oracle > 1e-2) & (oracle < reach - 1e-2)  # outside: shapely says 0 inside
        near += within.sum()
        np.testing.assert_allclose(np.asarray(found.value)[within], oracle[within], atol=2e-3)
        named = []  # shapely's distance from the slot each such link's nearest names
        segments = shapely.linestrings(np.stack([start, end], -2))
        for segment, code, row, position in zip(
                segments[within], *(np.asarray(a)[within] for a in found[1:])):
            numbers = [np.asarray(a[row, position], np.float64)
                       for a in getattr(tables, f"{nearby.KINDS[code]}s")]
            if nearby.KINDS[code] == "circle":
                x, y, radius = numbers[0]
                named.append(shapely.distance(segment, shapely.Point(x, y)) - radius)
            else:  # the polygon's valid vertices
                corners = numbers[0][numbers[POLYGON_FIELDS.index("edge_valid")].astype(bool)]
                named.append(shapely.distance(segment, shapely.Polygon(corners)))
        np.testing.assert_allclose(named, oracle[within], atol=2e-3)
    assert 100 < near < ARM.n_joints * 400  # links near an obstacle, and others not


@pytest.mark.parametrize("kind", ["triangles", pytest.param("mixed", marks=pytest.mark.slow)])
def test_clearances_by_the_nearest_slot_have_the_values_and_gradients_of_every_block(rng, kind):
    """``link_clearance_bounds(by_nearest=True)`` (refine's barrier): the same values (bit for
    bit undifferentiated; differentiated, from the nearest pass, within float32 rounding) and
    the same reverse-mode derivatives up to float32 rounding (other programs) as
    differentiating through every block; forward mode agreeing with reverse mode; zero
    derivatives where the tables' reach bounds the clearance."""
    # the sampled check's tables (blocks of 4 polygons): the gradient through every block
    # compiles faster
    problem = (mixed_problem(rng, "sampled") if kind == "mixed"
               else corridor_problem(rng, 300, kind, "sampled"))
    world = problem.arrays.world
    theta = [jnp.asarray(rng.uniform(-3, 3, 300), jnp.float32) for _ in range(ARM.n_joints)]

    def bounds(theta, by_nearest):
        return collision.link_clearance_bounds(ARM.lengths, world,
                                               link_endpoints(ARM.lengths, theta),
                                               exact=False, by_nearest=by_nearest)

    def per_posture(theta, by_nearest):  # posture i's value depends on posture i alone
        return sum(jnp.sin(bound) for bound in bounds(theta, by_nearest))

    def assert_close(one, other):  # float32 rounding of the largest, and no more
        other = np.asarray(other)
        assert np.abs(other).max() > 0
        np.testing.assert_allclose(one, other, rtol=0, atol=1e-6 * np.abs(other).max())
    values = [jax.jit(bounds, static_argnums=1)(theta, flag) for flag in (True, False)]
    for one, other in zip(*values):  # not differentiated: the same program
        np.testing.assert_array_equal(one, other)
    reverse = [jax.jit(jax.grad(lambda theta, flag: jnp.sum(per_posture(theta, flag))),
                       static_argnums=1)(theta, flag) for flag in (True, False)]
    for joint in range(ARM.n_joints):
        assert_close(reverse[0][joint], reverse[1][joint])
    direction = [jnp.asarray(rng.normal(size=300), jnp.float32) for _ in theta]
    (differentiated, _), (along, forward) = jax.jit(lambda theta, d: jax.jvp(
        lambda theta: (bounds(theta, True), per_posture(theta, True)), (theta,), (d,)))(
        theta, direction)
    for one, other in zip(differentiated, values[1]):  # the nearest pass's own values
        np.testing.assert_allclose(one, other, rtol=0, atol=1e-4)
    assert_close(forward, sum(g * d for g, d in zip(reverse[1], direction)))
    last = along[-1]
    beyond = np.asarray(values[0][-1]) >= float(world.near.reach)
    assert 0 < beyond.sum() < len(beyond)
    np.testing.assert_array_equal(np.asarray(last)[beyond], 0.0)
    assert np.all(np.asarray(last)[~beyond] != 0.0)


def test_clearances_by_the_nearest_slot_take_the_cheaper_bound_alone(rng):
    """The nearest pass is built and tested on the cheaper bound: asked for exact distances,
    it says so rather than giving them untested."""
    world = corridor_problem(rng, 100, "circles", "sampled").arrays.world
    links = link_endpoints(ARM.lengths, [jnp.zeros(3, jnp.float32)] * ARM.n_joints)
    for near in (world.near, None):  # with near tables or not
        with pytest.raises(ValueError, match="by_nearest takes the cheaper bound.*exact=True"):
            collision.link_clearance_bounds(ARM.lengths, world._replace(near=near), links,
                                            exact=True, by_nearest=True)


@pytest.mark.parametrize("margin, every_slot", [(0.0, False), (1.0, False), (0.0, True),
                                               (1.0, True)])
def test_the_sampled_check_gives_the_same_verdicts_with_and_without_tables(
        rng, monkeypatch, margin, every_slot):
    # just past the broad phase's threshold: testing every slot compiles slowly past it
    if not every_slot:  # the grid's lists, not one list of every slot
        monkeypatch.setattr(nearby, "EVERY_SLOT_EDGES", 0)
    problem = corridor_problem(rng, nearby.BROAD_PHASE_WORK // 3 + 1, "triangles",
                               collision="sampled", margin=margin)
    assert nearby.lists_every_slot(problem.arrays.world.near) == every_slot
    x = rng.uniform(-60, 60, (500, problem.n_free)).astype(np.float32)
    run = jax.jit(lambda arrays, x: evaluate(problem.spec, arrays, x))
    near, every = run(problem.arrays, x), run(without_tables(problem), x)
    np.testing.assert_array_equal(near.fitness, every.fitness)
    # A depth is a difference of coordinates up to the arm's reach, which each program rounds
    # in its own order: equal up to a float32 spacing at the reach (and never 0 against > 0,
    # which the fitness above would show).
    atol = np.spacing(np.float32(ARM.reach))
    np.testing.assert_allclose(near.violation, every.violation, rtol=1e-5, atol=atol)
    assert 0.2 < np.mean(np.asarray(near.fitness) > 0) < 0.99


@pytest.mark.parametrize("count, kind", [
    (nearby.BROAD_PHASE_WORK + 1, "circles"),
    pytest.param(nearby.BROAD_PHASE_WORK // 3 + 1, "triangles", marks=pytest.mark.slow)])
def test_the_certified_check_gives_the_same_verdicts_with_and_without_tables(rng, count, kind):
    """The grid's lists (circles) and one list of every slot (a few dozen triangles)."""
    problem = corridor_problem(rng, count, kind, margin=0.5)
    assert nearby.lists_every_slot(problem.arrays.world.near) == (kind == "triangles")
    x = rng.uniform(-60, 60, (400, problem.n_free)).astype(np.float32)
    run = jax.jit(lambda arrays, x: certified.check(problem.spec, arrays, x))
    near, every = run(problem.arrays, x), run(without_tables(problem), x)
    for field in ("free", "colliding", "exhausted"):
        np.testing.assert_array_equal(getattr(near, field), getattr(every, field))
    assert np.asarray(near.free).sum() > 100 and np.asarray(near.colliding).sum() > 10
    assert np.asarray(near.pieces).sum() > 0  # the bisection ran


@pytest.mark.parametrize("count, kind, collision", [
    (300, "circles", "certified"), (300, "triangles", "certified"),
    pytest.param(300, "triangles", "sampled", marks=pytest.mark.slow),
    (60, "triangles", "certified")])
def test_certified_free_among_hundreds_of_obstacles_is_free_for_the_dense_oracle(
        rng, count, kind, collision):
    """No path certified free comes closer than the margin at any of 20,001 times (shapely);
    paths the oracle finds clear by 2 tolerances are certified. ``certify`` of a sampled
    problem reads the sampled check's tables (a shorter reach, polygon blocks of 4); 60
    triangles get one list of every slot."""
    problem = corridor_problem(rng, count, kind, collision=collision, margin=0.25)
    assert nearby.lists_every_slot(problem.arrays.world.near) == (count < 100)
    x = rng.uniform(-60, 60, (300, problem.n_free))
    certificate = jaxarm.certify(problem, x)
    free = np.asarray(certificate.free)
    rows = np.concatenate([np.nonzero(free)[0][:20], np.nonzero(~free)[0][:8]])
    clearance = dense_clearance(problem, x[rows], 20_001, cutoff=2.0)
    assert free.sum() >= 20 and (~free).sum() >= 8
    assert np.all(clearance[free[rows]] >= problem.margin - 1e-4), clearance[free[rows]].min()
    clear = clearance >= problem.margin + 2 * problem.certify_tol
    assert np.all(free[rows][clear])


@pytest.mark.parametrize("check", ["sampled", pytest.param("certified", marks=pytest.mark.slow)])
def test_one_list_of_every_circle_and_polygon_gives_the_verdicts_of_every_slot(rng, check):
    """A world of 40 circles and 10 triangles reads one list of every slot: its padding
    circles lie more than 1e4 cm beyond the arm's reach, and each check's verdicts (and
    the sampled check's fitness) are those of every slot written out."""
    world = jaxarm.World(circles=corridor_world(rng, 40, "circles").circles,
                         polygons=corridor_world(rng, 10, "triangles").polygons)
    problem = corridor_problem(rng, None, None, collision=check, margin=0.5, world=world)
    tables = problem.arrays.world.near
    assert nearby.lists_every_slot(tables) and tables.circle_lists.shape[-1] == 48
    listed = tables.circles[0].reshape(-1, 3)
    real = np.isin(listed, np.asarray(problem.world.circles, np.float32)).all(axis=1)
    padding = listed[~real]
    assert real.sum() == 40 and np.all(np.hypot(*padding[:, :2].T) - padding[:, 2]
                                       > 1e4 + ARM.reach)
    x = rng.uniform(-60, 60, (400, problem.n_free)).astype(np.float32)
    if check == "sampled":
        run = jax.jit(lambda arrays, x: evaluate(problem.spec, arrays, x))
        near, every = run(problem.arrays, x), run(without_tables(problem), x)
        np.testing.assert_array_equal(near.fitness, every.fitness)
        assert 0.1 < np.mean(np.asarray(near.fitness) > 0) < 0.99
        return
    run = jax.jit(lambda arrays, x: certified.check(problem.spec, arrays, x))
    near, every = run(problem.arrays, x), run(without_tables(problem), x)
    for field in ("free", "colliding", "exhausted"):
        np.testing.assert_array_equal(getattr(near, field), getattr(every, field))
    assert np.asarray(near.free).sum() > 50 and np.asarray(near.colliding).sum() > 10


def test_a_world_of_a_thousand_obstacles_compiles_the_program_of_two_hundred(rng):
    """Obstacles are data: the traced check has as many operations for 1,000 circles as for
    200 (a Python loop over slots would add some for each)."""
    def size(count):
        problem = corridor_problem(rng, count, "circles")
        x = np.zeros((8, problem.n_free), np.float32)
        jaxpr = jax.make_jaxpr(lambda arrays, x: evaluate(problem.spec, arrays, x))(
            problem.arrays, x)
        return count_equations(jaxpr.jaxpr)
    assert size(1000) == size(200) > 1000


def count_equations(jaxpr) -> int:
    """Operations in a jaxpr, those of the programs it calls (loops, branches) included."""
    total = 0
    for equation in jaxpr.eqns:
        total += 1
        for parameter in equation.params.values():
            for inner in parameter if isinstance(parameter, (list, tuple)) else [parameter]:
                inner = getattr(inner, "jaxpr", inner)
                if hasattr(inner, "eqns"):
                    total += count_equations(inner)
    return total


def test_a_start_colliding_in_a_large_world_names_the_obstacle(rng):
    world = corridor_world(rng, 100, "circles")
    circles = list(world.circles)
    circles[77] = (55.0, 0.0, 2.0)  # on the first link at the start
    with pytest.raises(ValueError, match=r"start posture .* overlaps circles\[77\]"):
        jaxarm.Problem(arm=ARM, start=[0.0, 0.0, 0.0], goal=[0.5, 0.0, 0.0],
                       world=jaxarm.World(circles=circles))


def test_a_problems_arrays_are_placed_on_the_device_once_with_the_same_bits(rng):
    """``Problem.device_arrays``: the same placed arrays at every call (a world's tables are
    not copied to the device at each), of the types a compiled call gives the host's, and
    the check's bits from either."""
    from jaxarm.checks.evaluate import _evaluate_and_certify

    problem = corridor_problem(rng, nearby.BROAD_PHASE_WORK + 1, "circles", collision="sampled")
    x = rng.uniform(-60, 60, (64, problem.n_free)).astype(np.float32)
    in_a_trace = jax.jit(lambda: jaxarm.fitness(problem, x))()  # placed first in a trace
    placed = problem.device_arrays()
    assert placed is problem.device_arrays()
    host, device = jax.tree.leaves(problem.arrays), jax.tree.leaves(placed)
    assert len(host) == len(device) and all(isinstance(a, jax.Array) for a in device)
    assert [jax.typeof(a) for a in host] == [jax.typeof(a) for a in device]
    for a, b in zip(_evaluate_and_certify(problem.spec, problem.arrays, x)[0],
                    _evaluate_and_certify(problem.spec, placed, x)[0]):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(jaxarm.fitness(problem, x), in_a_trace)
    assert problem.replace(margin=0.5).device_arrays() is not placed
    assert "_device_arrays" not in pickle.loads(pickle.dumps(problem)).__dict__


def test_distinct_blocks_are_found_whether_their_keys_collide_or_not(rng):
    """``_distinct_rows``: every distinct block once, numbered in order of first appearance,
    the same when every key collides (the bytes sorted instead)."""
    blocks = rng.integers(0, 4, (600, 3)).astype(np.int32)  # 64 possible rows: many repeats
    first, rows = nearby._distinct_rows(blocks)
    assert len(first) == len(np.unique(blocks, axis=0)) and np.all(np.diff(first) > 0)
    np.testing.assert_array_equal(blocks[first][rows], blocks)
    assert rows[0] == 0 and np.all(np.diff(np.maximum.accumulate(rows)) <= 1)
    colliding = nearby._distinct_rows(blocks, weights=np.zeros(3, np.uint64))  # one key for all
    np.testing.assert_array_equal(colliding[0], first)
    np.testing.assert_array_equal(colliding[1], rows)


@pytest.mark.parametrize("first_empty", [0, 5, None])
def test_blocks_of_padding_alone_are_numbered_as_every_block_is(rng, first_empty):
    """``_distinct_blocks`` skips hashing the blocks of padding alone (a list's slots come
    first, so a block whose first slot is padding holds nothing else) and numbers every block
    as ``_distinct_rows`` does: with the first such block first, in the middle, or none."""
    n_slots = 6
    blocks = np.sort(rng.integers(0, n_slots + 1, (400, 2)), axis=1).astype(np.int32)
    blocks[:, 1] = np.where(blocks[:, 0] == n_slots, n_slots, blocks[:, 1])
    blocks[:5] = [0, 1]  # no padding before row 5, unless first_empty says otherwise
    if first_empty is None:
        blocks = blocks[blocks[:, 0] < n_slots]
    else:
        blocks[first_empty] = n_slots
    assert np.any(blocks[:, 0] == n_slots) == (first_empty is not None)
    expected = nearby._distinct_rows(blocks)
    for shape in ((1, len(blocks)), (len(blocks) // 5, 5) if len(blocks) % 5 == 0 else (1, -1)):
        found = nearby._distinct_blocks(blocks.reshape(*shape, 2), n_slots)  # (n_blocks, M, 2)
        np.testing.assert_array_equal(found[0], expected[0])
        np.testing.assert_array_equal(found[1], expected[1])
    everything_padding = np.full((1, 7, 2), n_slots, np.int32)
    np.testing.assert_array_equal(nearby._distinct_blocks(everything_padding, n_slots)[1], 0)


def test_near_pairs_come_in_order_of_list_and_slot(rng):
    """``_near_pairs`` gives its pairs sorted by list, then slot, each once (``_padded``
    relies on it, falling back to a sort)."""
    low = rng.uniform(-80, 80, (300, 2))
    high = low + rng.uniform(0, 6, (300, 2))
    centres = -80.0 + (160.0 / nearby.GRID_CELLS) * (np.arange(nearby.GRID_CELLS) + 0.5)
    everywhere = np.ones((nearby.GRID_CELLS, nearby.GRID_CELLS), bool)
    pairs = nearby._near_pairs(centres, low, high, 30.0, 5.0, everywhere)
    key = pairs.lists.astype(np.int64) * 301 + pairs.slots
    assert len(key) > 1000 and np.all(np.diff(key) > 0)


@pytest.mark.parametrize("lengths", [(30.0, 30.0, 20.0), (30.0, 5.0, 20.0, 4.0), (8.0,) * 10])
def test_every_cell_a_links_midpoint_reaches_has_its_list(rng, lengths):
    """``_reachable_cells``: the midpoint of every link, at 20,000 random postures (float32
    kinematics, the cell ``near_cells`` picks), lies in a cell the link's tables fill; and
    cells far from every midpoint are left empty (a ring for the first link)."""
    arm_reach = sum(lengths)
    cell = 2.0 * arm_reach / nearby.GRID_CELLS
    centres = -arm_reach + cell * (np.arange(nearby.GRID_CELLS) + 0.5)
    theta = [jnp.asarray(rng.uniform(-np.pi, np.pi, 20_000), jnp.float32) for _ in lengths]
    links = link_endpoints(jnp.asarray(lengths, jnp.float32), theta)
    tables = types.SimpleNamespace(
        circle_lists=np.zeros((1, 1, nearby.GRID_CELLS, nearby.GRID_CELLS, 1)),
        inverse_cell=1.0 / cell, origin=np.array([-arm_reach, -arm_reach]))
    for link, (sx, sy, ex, ey) in enumerate(links):
        reachable = nearby._reachable_cells(centres, cell, np.asarray(lengths[:link + 1]),
                                            1e-4 * arm_reach)
        row, column = nearby.cell_of(tables, 0.5 * (sx + ex), 0.5 * (sy + ey))
        assert reachable[np.asarray(row), np.asarray(column)].all(), link
        assert reachable.mean() < 0.9  # the grid's corners at least are out of reach
    first = nearby._reachable_cells(centres, cell, np.asarray(lengths[:1]), 1e-4 * arm_reach)
    radius = np.hypot(centres[:, None], centres[None, :])
    assert not first[np.abs(radius - 0.5 * lengths[0]) > cell].any()


def test_lists_are_filled_alike_from_pairs_in_any_order(rng):
    """``_padded``: pairs in order of list and slot (as ``_near_pairs`` gives them) and the same
    pairs shuffled fill the same lists, each list's slots ascending, padded with the count."""
    n_cells, n_slots = nearby.GRID_CELLS ** 2, 50
    pairs = np.unique(np.stack([rng.integers(0, nearby.DIRECTION_BINS * n_cells, 4800),
                                rng.integers(0, n_slots, 4800)], axis=1), axis=0)
    lists, slots = pairs[:, 0], pairs[:, 1]
    ordered = nearby._padded([(lists, slots)], n_slots, nearby.BLOCK)
    order = rng.permutation(len(lists))
    np.testing.assert_array_equal(
        nearby._padded([(lists[order], slots[order])], n_slots, nearby.BLOCK), ordered)
    direction, cell = divmod(int(lists[0]), n_cells)
    row, column = divmod(cell, nearby.GRID_CELLS)
    listed = ordered[0, direction, row, column]
    expected = np.sort(slots[lists == lists[0]])
    np.testing.assert_array_equal(listed[:len(expected)], expected)
    assert np.all(listed[len(expected):] == n_slots)
