"""Scenario files (TOML): the loader that turns one into a ``Problem``, and the writer back.

The shipped scenarios are ``jaxarm/scenarios/*.toml``.

Schema (units: cm and rad)::

    name = "paper-case-1"              # optional, defaults to the file name
    description = "one line"           # optional
    units = "cm, rad"                  # optional; the only units read (anything else: error)
    [arm]
    lengths = [30.0, 30.0, 20.0]
    masses = [3.0, 3.0, 2.0]           # optional, kg per link (uniform rods): for torques
    gravity = 9.81                     # optional, m/s^2 along -y (default 9.81; 0: horizontal)
    joint_limits = [[-3.2, 3.2], [-2.5, 2.5], [-2.5, 2.5]]   # optional, rad per joint
    self_collision = true              # optional: links that are not neighbours keep apart
    [start]                            # joint angles, or a pose solved by inverse kinematics
    joints = [-1.33, 2.03, -0.69]      #   (arms of 3 or more links, ``jaxarm.model.poses``;
    pose = { x = 50.0, y = -10.0, phi = 0.0, elbow = 1 }   # ``near = [...]``: the solution
                                       #   near that posture); both given: they must agree
    [goal]                             # same as [start]
    [search]                           # all optional
    degree = 6                         # polynomial degree, 6 to MAX_DEGREE (jaxarm.choices)
    samples = 101                      # odd
    collision = "certified"            # default; "sampled" is the paper's check at the samples
    margin = 0.0                       # cm every link keeps from every obstacle
    certify_tol = 0.01                 # cm: the certified check's tolerance
    certify_budget = 512               # most pieces the certified check tests per path
    capacities = [4, 0, 0]             # obstacle slots: circles, polygons, vertices per polygon
    init_low = -100.0                  # scalar or one value per free coefficient
    init_high = 100.0
    [[obstacles]]                      # any number of these
    type = "circle"                    # center = [x, y], radius = r
    type = "box"                       # min = [xmin, ymin], max = [xmax, ymax]
    type = "polygon"                   # vertices = [[x, y], ...], convex, either order
    type = "segment"                   # points = [[x0, y0], [x1, y1]]: a wall of zero thickness
    type = "map"                       # file = "room.yaml": a ROS map_server occupancy map,
                                       #   relative to the scenario file; unknown = "occupied"
                                       #   (default) or "free" (``jaxarm.io.occupancy_maps``)

Numbers must be ones float32, which the search computes in, holds: lengths, coordinates,
radii, ``margin`` and ``certify_tol`` within +-1e5 cm (``_validate.MAX_CM``), ``init_low`` and
``init_high`` within +-1e4 (``problem.MAX_COEFFICIENT``). An error names the key as written
here (``search.samples``, ``obstacles[2].center``).

``save_scenario`` (or ``to_toml``) writes a ``Problem`` in this schema, every key above that
has a value (``units`` and ``capacities`` included); loading the file gives back an equal
``Problem``.
"""

from __future__ import annotations

import importlib.resources
import os
import pathlib
import re
import tomllib

import numpy as np
import tomli_w

from jaxarm._validate import finite_scalar, finite_vector, renamed
from jaxarm.io import occupancy_maps
from jaxarm.model import world as world_lib
from jaxarm.model.arm import Arm
from jaxarm.model.poses import inverse_kinematics
from jaxarm.model.problem import Problem
from jaxarm.model.world import World


class ScenarioError(ValueError):
    """A scenario that cannot be loaded; the message names the file and the key."""


UNITS = "cm, rad"
SHIPPED = importlib.resources.files("jaxarm") / "scenarios"  # the shipped scenario files
_TOP_KEYS = {"name", "description", "units", "arm", "start", "goal", "search", "obstacles"}
# [search] key -> Problem field; a key left out keeps the Problem's default
_SEARCH_FIELDS = {"degree": "degree", "samples": "n_samples", "collision": "collision",
                  "init_low": "init_low", "init_high": "init_high", "margin": "margin",
                  "certify_tol": "certify_tol", "certify_budget": "certify_budget",
                  "capacities": "capacities"}
# Problem field -> its key in a scenario file, for the errors a Problem raises
_FIELD_KEYS = {field: f"search.{key}" for key, field in _SEARCH_FIELDS.items()} | {
    "joint_limits": "arm.joint_limits"}
POSE_TOLERANCE = 1e-6  # cm and rad: how closely a posture's joints and pose must agree
_OBSTACLE_KEYS = {
    "circle": {"type", "center", "radius"},
    "box": {"type", "min", "max"},
    "polygon": {"type", "vertices"},
    "segment": {"type", "points"},
    "map": {"type", "file", "unknown"},
}
_REQUIRED_KEYS = {"map": {"type", "file"}}


def available() -> dict[str, str]:
    """Shipped scenario names with their one-line descriptions, sorted by name."""
    out = {}
    for entry in sorted(SHIPPED.iterdir(), key=lambda e: e.name):
        if entry.name.endswith(".toml"):
            data = tomllib.loads(entry.read_text(encoding="utf-8"))
            out[entry.name[: -len(".toml")]] = data.get("description", "")
    return out


def load_scenario(name_or_path: str | pathlib.Path, **overrides) -> Problem:
    """Load a shipped scenario by name, or a scenario file by path.

    Args:
      name_or_path: a name from ``available()`` (e.g. ``"paper-case-1"``) or a path to a .toml.
      **overrides: ``Problem`` fields to replace (e.g. ``collision="sampled"``).

    Returns:
      The ``Problem``.

    Raises:
      ScenarioError: unknown name, unreadable file, malformed TOML (with line and column),
        a missing or unknown key, or invalid values (naming the key).

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2", collision="sampled")
      >>> problem.name, problem.n_free, problem.collision
      ('paper-case-2', 3, 'sampled')
    """
    text, source, folder = _read(name_or_path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ScenarioError(f"{source}: malformed TOML: {error}") from None
    try:
        problem = _problem(data, default_name=pathlib.Path(source).stem, folder=folder)
        return problem.replace(**overrides) if overrides else problem
    except (ValueError, TypeError) as error:  # ScenarioError is a ValueError
        raise ScenarioError(f"{source}: {error}") from None


def obstacle_names(name_or_path: str | pathlib.Path) -> dict[str, str]:
    """Each obstacle's name in ``World`` (``"boxes[0]"``) -> its name in the scenario file
    (``"obstacles[3]"``, a map's boxes ``"obstacles[3] (box 12 of room.yaml)"``), for
    messages about a problem ``load_scenario(name_or_path)`` loaded."""
    try:
        text, _, folder = _read(name_or_path)
        return _obstacles(tomllib.loads(text).get("obstacles", []), folder)[1]
    except (ValueError, TypeError):  # the file changed or went since it loaded: World's names
        return {}


def _read(name_or_path) -> tuple[str, str, pathlib.Path]:
    """The scenario's text, its name in messages, and the folder its maps are relative to."""
    if not isinstance(name_or_path, (str, os.PathLike)) or not str(name_or_path).strip():
        raise ScenarioError(f"scenario must be a shipped name or a path to a .toml file, got "
                            f"{name_or_path!r}; shipped scenarios: {', '.join(available())}")
    candidate = pathlib.Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.exists():
        try:
            return candidate.read_text(encoding="utf-8"), str(candidate), candidate.parent
        except OSError as error:
            raise ScenarioError(f"cannot read scenario file {str(candidate)!r}: {error.strerror}")
        except UnicodeDecodeError as error:
            raise ScenarioError(f"{candidate}: not UTF-8 text, as TOML must be ({error.reason} at "
                                f"byte {error.start})") from None
    resource = SHIPPED / f"{name_or_path}.toml"
    if not resource.is_file():
        names = ", ".join(available())
        raise ScenarioError(f"unknown scenario {str(name_or_path)!r}; shipped scenarios: {names}")
    return (resource.read_text(encoding="utf-8"), f"{name_or_path}.toml",
            pathlib.Path(str(SHIPPED)))


def _table(data: dict, key: str, required: bool = True) -> dict:
    value = data.get(key)
    if value is None and not required:
        return {}
    if not isinstance(value, dict):
        raise ScenarioError(f"[{key}] must be a table, got {value!r}")
    return value


def _unknown(table: dict, allowed: set, where: str) -> None:
    extra = sorted(set(table) - allowed)
    if extra:
        raise ScenarioError(f"unknown key {where}{extra[0]!r}; allowed: {sorted(allowed)}")


def _posture(data: dict, which: str, arm: Arm):
    table = _table(data, which)
    _unknown(table, {"joints", "pose"}, f"in [{which}]: ")
    if "pose" not in table:
        if "joints" not in table:
            raise ScenarioError(f"[{which}] needs 'joints' or 'pose'")
        return table["joints"]
    pose = table["pose"]
    if not isinstance(pose, dict) or not {"x", "y"} <= set(pose):
        raise ScenarioError(f"{which}.pose must be {{x, y, phi, elbow, near}}, got {pose!r}")
    _unknown(pose, {"x", "y", "phi", "elbow", "near"}, f"in {which}.pose: ")
    try:
        joints = inverse_kinematics(arm, pose["x"], pose["y"], pose.get("phi", 0.0),
                                    pose.get("elbow", 1), pose.get("near"))
    except ValueError as error:
        message = str(error)  # "pose.near must ...", "pose (x=...) is unreachable", ...
        raise ScenarioError(f"{which}.{message}" if message.startswith("pose") else
                            f"{which}.pose: {message}") from None
    if "joints" in table:
        _check_agreement(which, arm, table["joints"], pose)
    return joints


def _check_agreement(which: str, arm: Arm, joints, pose: dict) -> None:
    """A posture given both ways must be the same posture."""
    given = finite_vector(f"{which}.joints", joints, arm.n_joints)
    absolute = np.cumsum(given)  # each link's angle in the plane (paper eqs. 1-4)
    x, y = (float(np.dot(arm.lengths, f(absolute))) for f in (np.cos, np.sin))
    phi = float(absolute[-1])
    wrapped = (phi - float(pose.get("phi", 0.0)) + np.pi) % (2 * np.pi) - np.pi
    elbow = 1 if np.sin(given[1]) >= 0 else -1
    elbow_counts = arm.n_joints == 3 and "near" not in pose  # it picks the closed form's
    if (max(abs(x - pose["x"]), abs(y - pose["y"]), abs(wrapped)) > POSE_TOLERANCE
            or elbow_counts and elbow != pose.get("elbow", 1)):
        raise ScenarioError(
            f"{which}.joints {given.tolist()} and {which}.pose {pose} disagree: the joints put "
            f"the end-effector at x = {x:.6g}, y = {y:.6g}, phi = {phi:.6g}, elbow {elbow:+d}; "
            "give one of them")


def _obstacles(entries, folder: pathlib.Path) -> tuple[World, dict[str, str]]:
    """The world, and each obstacle's ``World`` name (``"boxes[0]"``) -> its name in the file
    (``"obstacles[3]"``; a map's boxes: ``"obstacles[3] (box 12 of room.yaml)"``). Maps are
    read relative to ``folder``."""
    if not isinstance(entries, list):
        raise ScenarioError(f"obstacles must be an array of tables, got {entries!r}")
    circles, boxes, polygons, segments = [], [], [], []
    kinds = {"circle": ("circles", circles), "box": ("boxes", boxes),
             "polygon": ("polygons", polygons), "segment": ("segments", segments)}
    names = {}
    for index, entry in enumerate(entries):
        where = f"obstacles[{index}]"
        kind = entry.get("type") if isinstance(entry, dict) else None
        if kind not in _OBSTACLE_KEYS:
            raise ScenarioError(f"{where}.type must be circle, box, polygon, segment or map, got "
                                f"{kind!r}")
        _unknown(entry, _OBSTACLE_KEYS[kind], f"in {where}: ")
        missing = sorted(_REQUIRED_KEYS.get(kind, _OBSTACLE_KEYS[kind]) - set(entry))
        if missing:
            raise ScenarioError(f"{where} ({kind}) is missing {missing[0]!r}")
        try:
            if kind == "circle":
                center = finite_vector(f"{where}.center", entry["center"], length=2)
                radius = finite_scalar(f"{where}.radius", entry["radius"])
                circles.append(world_lib.check_circle(where, (*center, radius)))
            elif kind == "box":
                boxes.append(world_lib.check_box(where, (entry["min"], entry["max"])))
            elif kind == "map":
                file = entry["file"]
                if not isinstance(file, str):
                    raise ValueError(f"{where}.file must be a path to a map's YAML file, got "
                                     f"{file!r}")
                try:
                    grid = occupancy_maps.load_map(folder / file,
                                                   entry.get("unknown", "occupied"))
                except ValueError as error:
                    raise ValueError(f"{where}: {error}") from None
                for number, box in enumerate(grid.boxes()):
                    boxes.append(world_lib.check_box(where, box))
                    names[f"boxes[{len(boxes) - 1}]"] = f"{where} (box {number} of {file})"
                continue
            elif kind == "segment":
                segments.append(world_lib.check_segment(where, entry["points"]))
            else:
                polygons.append(world_lib.check_polygon(where, entry["vertices"]))
        except (ValueError, TypeError) as error:
            raise ScenarioError(str(error)) from None
        field, added = kinds[kind]
        names[f"{field}[{len(added) - 1}]"] = where
    return World(circles=circles, boxes=boxes, polygons=polygons, segments=segments), names


def _problem(data: dict, default_name: str, folder: pathlib.Path = pathlib.Path(".")) -> Problem:
    _unknown(data, _TOP_KEYS, "")
    if data.get("units", UNITS) != UNITS:
        raise ScenarioError(f"units must be {UNITS!r} (lengths in cm, angles in rad), "
                            f"got {data['units']!r}")
    arm_table = _table(data, "arm")
    _unknown(arm_table, {"lengths", "masses", "gravity", "joint_limits", "self_collision"},
             "in [arm]: ")
    if "lengths" not in arm_table:
        raise ScenarioError("[arm] needs 'lengths'")
    arm = Arm(lengths=arm_table["lengths"], masses=arm_table.get("masses"),
              gravity=arm_table.get("gravity", Arm.gravity),
              self_collision=arm_table.get("self_collision", False))
    search = _table(data, "search", required=False)
    _unknown(search, set(_SEARCH_FIELDS), "in [search]: ")
    fields = {field: search[key] for key, field in _SEARCH_FIELDS.items() if key in search}
    start, goal = _posture(data, "start", arm), _posture(data, "goal", arm)
    world, obstacle_names = _obstacles(data.get("obstacles", []), folder)
    try:
        return Problem(arm=arm, start=start, goal=goal, world=world,
                       name=str(data.get("name", default_name)),
                       description=str(data.get("description", "")),
                       joint_limits=arm_table.get("joint_limits"), **fields)
    except ValueError as error:  # named as the file names it: search.samples, not n_samples,
        message = renamed(str(error), _FIELD_KEYS)  # and obstacles[3], not boxes[0]
        raise ScenarioError(with_file_names(message, obstacle_names)) from None


def with_file_names(message: str, names: dict) -> str:
    """``message`` with ``World``'s obstacle names (``"boxes[0]"``) as the scenario file
    names them (``names``: ``obstacle_names``' map; a name it lacks stays)."""
    return re.sub(r"\b(circles|boxes|polygons|segments)\[\d+\]",
                  lambda m: names.get(m.group(), m.group()), message)


def problem_from_table(table: dict) -> Problem:
    """The problem that a scenario table describes (a parsed scenario file, or
    ``scenario_table``'s output; a map's file is relative to the working directory); a
    missing, unknown or invalid key raises ``ScenarioError`` naming it."""
    try:
        return _problem(table, "unnamed")
    except (ValueError, TypeError) as error:
        raise ScenarioError(str(error)) from None


def scenario_table(problem: Problem) -> dict:
    """``problem`` in the scenario schema, as plain dicts, lists and numbers."""
    world = problem.world
    obstacles = ([{"type": "circle", "center": [x, y], "radius": r} for x, y, r in world.circles]
                 + [{"type": "box", "min": list(low), "max": list(high)}
                    for low, high in world.boxes]
                 + [{"type": "polygon", "vertices": [list(v) for v in polygon]}
                    for polygon in world.polygons]
                 + [{"type": "segment", "points": [list(p) for p in segment]}
                    for segment in world.segments])
    plain = (lambda v: list(v) if isinstance(v, tuple) else v)  # TOML arrays from tuples
    return {
        "name": problem.name,
        "description": problem.description,
        "units": UNITS,
        "arm": _arm_table(problem),
        "start": {"joints": list(problem.start)},
        "goal": {"joints": list(problem.goal)},
        "search": {key: plain(getattr(problem, field)) for key, field in _SEARCH_FIELDS.items()},
        "obstacles": obstacles,
    }


def _arm_table(problem: Problem) -> dict:
    arm = problem.arm
    table = {"lengths": list(arm.lengths)}
    if arm.masses is not None:
        table["masses"] = list(arm.masses)
    if arm.gravity != Arm.gravity:
        table["gravity"] = arm.gravity
    if arm.self_collision:
        table["self_collision"] = True
    if problem.joint_limits is not None:
        table["joint_limits"] = [list(pair) for pair in problem.joint_limits]
    return table


def to_toml(problem: Problem) -> str:
    """``problem`` as scenario-file text (postures as joints, floats written exactly, arrays on
    one line as in the shipped files)."""
    table = scenario_table(problem)
    obstacles = table.pop("obstacles")
    blocks = ["\n".join(_toml_lines({k: v for k, v in table.items() if not isinstance(v, dict)}))]
    blocks += ["\n".join([f"[{key}]", *_toml_lines(value)]) for key, value in table.items()
               if isinstance(value, dict)]
    blocks += ["\n".join(["[[obstacles]]", *_toml_lines(entry)]) for entry in obstacles]
    return "\n\n".join(blocks) + "\n"


def _toml_lines(table: dict) -> list[str]:
    return [f"{key} = {_toml_value(value)}" for key, value in table.items()]


def _toml_value(value) -> str:
    """One TOML value on one line: arrays inline, scalars as ``tomli_w`` writes them."""
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(map(_toml_value, value)) + "]"
    return tomli_w.dumps({"v": value}).removeprefix("v = ").rstrip("\n")


def save_scenario(problem: Problem, path: str | pathlib.Path) -> pathlib.Path:
    """Write ``problem`` as a scenario file that ``load_scenario(path)`` reads back equal.

    Returns:
      The path written.
    """
    path = pathlib.Path(path)
    if path.suffix != ".toml":
        raise ValueError(f"path must end in .toml, got {str(path)!r}")
    path.write_text(to_toml(problem), encoding="utf-8")
    return path
