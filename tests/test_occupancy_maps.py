"""Occupancy maps (``jaxarm.io.occupancy_maps``): map_server's reading of the pixels, the boxes
that cover exactly the occupied cells, scenario files that name a map, and one-line errors."""

import numpy as np
import pytest
from PIL import Image

import jaxarm
from jaxarm.io.occupancy_maps import load_map, occupied_boxes
from jaxarm.io.scenario_files import ScenarioError
from jaxarm.testing import dense_clearance


def write_map(folder, pixels, name="room", image_suffix=".pgm", **keys):
    """A map of ``pixels`` (uint8, row 0 the top) and its YAML file; returns the YAML path."""
    Image.fromarray(np.asarray(pixels, np.uint8)).save(folder / f"{name}{image_suffix}")
    settings = {"image": f"{name}{image_suffix}", "resolution": 0.01,
                "origin": [-0.5, -0.25, 0.0], "negate": 0, "occupied_thresh": 0.65,
                "free_thresh": 0.196} | keys
    lines = [f"{key}: {value}" for key, value in settings.items() if value is not None]
    path = folder / f"{name}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_boxes_cover_exactly_the_occupied_cells(rng):
    for _ in range(300):
        occupied = rng.uniform(size=rng.integers(1, 25, 2)) < rng.uniform()
        cover = np.zeros(occupied.shape, int)
        for top, bottom, left, right in occupied_boxes(occupied):
            cover[top:bottom, left:right] += 1
        np.testing.assert_array_equal(cover, occupied)  # every cell once, no free cell


def test_pixels_read_as_map_server_reads_them(tmp_path):
    # occupancy (255 - p) / 255: 0 -> 1 occupied, 254 -> free, 205 -> 0.196 unknown
    pixels = [[0, 254, 205], [254, 254, 254]]
    grid = load_map(write_map(tmp_path, pixels))
    np.testing.assert_array_equal(grid.occupied, [[True, False, True], [False, False, False]])
    free = load_map(write_map(tmp_path, pixels), unknown="free")
    np.testing.assert_array_equal(free.occupied, [[True, False, False], [False, False, False]])
    negated = load_map(write_map(tmp_path, pixels, negate=1))
    np.testing.assert_array_equal(negated.occupied, [[False, True, True], [True, True, True]])


def test_row_zero_is_the_top_and_units_are_cm(tmp_path):
    pixels = np.full((3, 4), 254)
    pixels[0, 1] = 0  # top row, second column
    grid = load_map(write_map(tmp_path, pixels))  # 1 cm cells, lower-left corner (-50, -25)
    assert grid.resolution == pytest.approx(1.0)
    [((xmin, ymin), (xmax, ymax))] = grid.boxes()
    assert (xmin, xmax) == pytest.approx((-49.0, -48.0))
    assert (ymin, ymax) == pytest.approx((-23.0, -22.0))


def test_a_colour_png_averages_its_channels(tmp_path):
    rgb = np.zeros((2, 2, 3), np.uint8)
    rgb[0, 0] = (254, 254, 254)
    rgb[1, 1] = (0, 254, 254)  # mean 169: occupancy 0.337, unknown
    Image.fromarray(rgb).save(tmp_path / "room.png")
    path = write_map(tmp_path, np.zeros((1, 1)), image_suffix=".png")
    Image.fromarray(rgb).save(tmp_path / "room.png")
    grid = load_map(path, unknown="free")
    np.testing.assert_array_equal(grid.occupied, [[False, True], [True, False]])


def test_a_yaml_syntax_error_names_its_line(tmp_path):
    path = tmp_path / "room.yaml"
    path.write_text("image: room.png\nresolution: [0.01\norigin: [-1.0, -1.0, 0.0]\n")
    with pytest.raises(ValueError, match=r"room.yaml: not a YAML map \(while parsing a flow "
                                         r"sequence at line 2, column 13: expected ',' or ']', "
                                         r"but got .* at line 3, column 7\)"):
        load_map(path)
    path.write_bytes(b"image: caf\xe9.png\n")  # Latin-1, not UTF-8
    with pytest.raises(ValueError, match=r"room.yaml: not a YAML map \(not UTF-8 text: byte 10\)"):
        load_map(path)


@pytest.mark.parametrize("suffix", [".png", ".pgm"])
@pytest.mark.parametrize("negate", [0, 1])
def test_sixteen_bit_greyscale_is_read_on_its_own_scale(tmp_path, suffix, negate):
    """A 16-bit PNG (Pillow's mode "I;16") or PGM ("I"): occupancy (65535 - p) / 65535, the
    same cells as the 8-bit image of the same shades; clipped to 8 bits, every shade past 255
    read as white (free)."""
    shades = np.array([[0, 254, 205], [254, 40, 150]])  # 40: 0.84 occupied; 150: 0.41 unknown
    eight = write_map(tmp_path, shades, name="eight", negate=negate)
    sixteen = write_map(tmp_path, np.zeros((1, 1)), name="sixteen", image_suffix=suffix,
                        negate=negate)
    image = Image.fromarray((shades * 257).astype(np.uint16))  # 255 * 257 = 65535
    image.save(tmp_path / f"sixteen{suffix}")
    with Image.open(tmp_path / f"sixteen{suffix}") as saved:
        assert saved.mode in {".png": ("I;16", "I"), ".pgm": ("I",)}[suffix]  # by Pillow
    for unknown in ("occupied", "free"):
        np.testing.assert_array_equal(load_map(sixteen, unknown=unknown).occupied,
                                      load_map(eight, unknown=unknown).occupied)
    expected = {0: [[True, False, True], [False, True, True]],  # 205, 150 unknown
                1: [[False, True, True], [True, False, True]]}[negate]  # 150 unknown
    np.testing.assert_array_equal(load_map(sixteen).occupied, expected)


@pytest.mark.parametrize("pixels, message", [
    (np.full((2, 2), 0.5, np.float32), r"holds floating-point pixels \(mode 'F'\)"),
    (np.full((2, 2), 255, np.int32), r"holds 32-bit integer pixels \(mode 'I'\)"),
])
def test_images_of_no_known_scale_get_one_line(tmp_path, pixels, message):
    path = write_map(tmp_path, np.zeros((1, 1)), image_suffix=".tiff")
    Image.fromarray(pixels).save(tmp_path / "room.tiff")
    with pytest.raises(ValueError, match=r"room.yaml: image '.*room.tiff' " + message):
        load_map(path)


@pytest.mark.parametrize("keys, message", [
    ({"image": "missing.pgm"}, r"image '.*missing.pgm' not found"),
    ({"free_thresh": 0.7}, r"free_thresh <= occupied_thresh"),
    ({"occupied_thresh": 1.5}, r"occupied_thresh <= 1"),
    ({"origin": [0.0, 0.0, 0.3]}, r"origin yaw must be 0"),
    ({"resolution": 0}, r"resolution must be > 0"),
    ({"resolution": None}, r"missing 'resolution'"),
    ({"negate": 2}, r"negate must be 0 or 1"),
    ({"mode": "scale"}, r"mode must be 'trinary'"),
    ({"colour": 1}, r"unknown key 'colour'"),
])
def test_a_bad_map_gets_one_line_naming_the_key(tmp_path, keys, message):
    path = write_map(tmp_path, np.full((4, 4), 254), **keys)
    with pytest.raises(ValueError, match=message) as error:
        load_map(path)
    assert "\n" not in str(error.value) and str(path) in str(error.value)


def test_a_missing_map_file_and_a_wrong_unknown_value(tmp_path):
    with pytest.raises(ValueError, match=r"cannot read map '.*nowhere.yaml'"):
        load_map(tmp_path / "nowhere.yaml")
    with pytest.raises(ValueError, match=r"unknown must be one of"):
        load_map(write_map(tmp_path, np.full((2, 2), 254)), unknown="maybe")


SCENARIO = """
name = "{name}"
[arm]
lengths = [30.0, 30.0, 20.0]
[start]
joints = [{start}, 0.0, 0.0]
[goal]
joints = [0.5, 0.0, 0.0]
[[obstacles]]
type = "circle"
center = [0.0, -70.0]
radius = 3.0
[[obstacles]]
type = "map"
file = "maps/room.yaml"
{extra}
"""


def test_a_scenario_names_a_map_relative_to_itself(tmp_path):
    (tmp_path / "maps").mkdir()
    pixels = np.full((200, 200), 254)  # 2 m square at 1 cm, the base at its centre
    pixels[40:60, 20:30] = 0  # x -80..-70, y 40..60
    pixels[150:152, 150:190] = 205  # unknown: x 50..90, y -52..-50
    write_map(tmp_path / "maps", pixels, origin=[-1.0, -1.0, 0.0])
    path = tmp_path / "scenario.toml"
    path.write_text(SCENARIO.format(name="room", start=0.0, extra=""))
    problem = jaxarm.load_scenario(path)
    assert len(problem.world.circles) == 1 and len(problem.world.boxes) == 2
    path.write_text(SCENARIO.format(name="room", start=0.0, extra='unknown = "free"'))
    assert len(jaxarm.load_scenario(path).world.boxes) == 1


def test_a_posture_on_an_occupied_cell_names_the_map(tmp_path):
    (tmp_path / "maps").mkdir()
    pixels = np.full((200, 200), 254)
    pixels[95:105, 150:160] = 0  # x 50..60 across y = 0: the start's second link
    write_map(tmp_path / "maps", pixels, origin=[-1.0, -1.0, 0.0])
    path = tmp_path / "scenario.toml"
    path.write_text(SCENARIO.format(name="room", start=0.0, extra=""))
    with pytest.raises(ScenarioError, match=r"start posture .* overlaps obstacles\[1\] \(box 0 "
                                            r"of maps/room.yaml\)"):
        jaxarm.load_scenario(path)


def test_a_scenario_with_a_bad_map_says_which_obstacle(tmp_path):
    path = tmp_path / "scenario.toml"
    path.write_text(SCENARIO.format(name="room", start=0.0, extra=""))
    with pytest.raises(ScenarioError, match=r"obstacles\[1\]: cannot read map"):
        jaxarm.load_scenario(path)
    path.write_text(SCENARIO.format(name="room", start=0.0, extra="colour = 1"))
    with pytest.raises(ScenarioError, match=r"unknown key in obstacles\[1\]: 'colour'"):
        jaxarm.load_scenario(path)


def test_the_shipped_map_scene_is_certified_free_by_the_default_search():
    problem = jaxarm.load_scenario("workcell-map")
    assert problem.world.n_obstacles > 100 and problem.arrays.world.near is not None
    result = jaxarm.solve(problem, n_restarts=4)
    assert result.certified
    # the dense oracle (shapely, 20,001 times) finds the certified path clear of every cell
    assert dense_clearance(problem, np.asarray(result.best_x)[None], 20_001, cutoff=2.0)[0] >= 0
