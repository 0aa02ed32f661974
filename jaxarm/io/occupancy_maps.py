"""Occupancy maps in the ROS ``map_server`` format, as obstacles.

A map is a YAML file beside an image (PGM, PNG or anything Pillow reads)::

    image: room.png              # relative to the YAML file
    resolution: 0.005            # metres per pixel
    origin: [-1.28, -1.28, 0.0]  # x, y, yaw of the lower-left pixel's corner, metres and rad
    negate: 0                    # 1: white is occupied
    occupied_thresh: 0.65        # occupancy above this: occupied
    free_thresh: 0.196           # below this: free; in between: unknown
    mode: trinary                # optional; the only mode read

As ``map_server`` reads it: a pixel's value p (0-255, the mean of its colour channels) has
occupancy ``(255 - p) / 255`` (``p / 255`` with ``negate: 1``); greyscale deeper than 8 bits
(16-bit PNG, PGM past 255) on its own scale, 0-65535, as nav2's ``map_server`` reads any depth;
row 0 of the image is the top of the map. Units become cm. The map's frame is the arm's: its
base at (0, 0). Unknown cells count as occupied unless ``unknown="free"``.

Every occupied cell becomes part of an obstacle: runs of occupied cells along each row are
merged, then runs spanning the same columns in consecutive rows, into axis-aligned boxes that
cover exactly the occupied cells (``occupied_boxes``). The checks treat them as any boxes, so
the certified check proves a motion clear of every occupied cell.
"""

from __future__ import annotations

import math
import pathlib
from typing import NamedTuple

import numpy as np

from jaxarm.model.world import World

UNKNOWN = ("occupied", "free")
# The modes Pillow opens greyscale deeper than 8 bits as (16-bit PNG; PGM past 255, which it
# scales to 0-65535, as mode "I"): read on that scale, never clipped to 8 bits. Mode "I" from
# another format (a TIFF's 32-bit integers) has no known scale: refused.
_DEEP_GREY = ("I;16", "I;16B", "I;16L", "I;16N")
_DEEP_GREY_AS_I = ("PPM", "PNG")  # formats whose mode "I" is greyscale scaled to 0-65535
_KEYS = {"image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode"}


class OccupancyMap(NamedTuple):
    """A map read from its YAML file: which cells are occupied, and where they lie."""

    occupied: np.ndarray  # shape=(rows, columns), bool; row 0 is the top of the map
    resolution: float  # cm per cell
    origin: tuple[float, float]  # cm: the lower-left corner of the bottom-left cell
    source: str  # the YAML file, as given

    def boxes(self) -> list[tuple[tuple[float, float], tuple[float, float]]]:
        """The occupied cells as boxes ``((xmin, ymin), (xmax, ymax))`` in cm."""
        rows = self.occupied.shape[0]
        out = []
        for top, bottom, left, right in occupied_boxes(self.occupied):
            xmin = self.origin[0] + left * self.resolution
            xmax = self.origin[0] + right * self.resolution
            ymin = self.origin[1] + (rows - bottom) * self.resolution
            ymax = self.origin[1] + (rows - top) * self.resolution
            out.append(((xmin, ymin), (xmax, ymax)))
        return out

    def world(self) -> World:
        """The map as a ``World`` of boxes."""
        return World(boxes=self.boxes())


def load_map(path: str | pathlib.Path, unknown: str = "occupied") -> OccupancyMap:
    """Read a ``map_server`` map (its YAML file).

    Args:
      path: the YAML file.
      unknown: what cells between the thresholds are, ``"occupied"`` or ``"free"``.

    Returns:
      ``OccupancyMap``.

    Raises:
      ValueError: one line naming the file and the key: a missing or unreadable file or
        image, an image of floating-point or 32-bit integer pixels, a threshold
        outside [0, 1] or free above occupied, a resolution <= 0, a yaw other than 0, an
        unknown key or mode.
    """
    import yaml  # PyYAML, as ROS itself reads these files

    if unknown not in UNKNOWN:
        raise ValueError(f"unknown must be one of {UNKNOWN}, got {unknown!r}")
    path = pathlib.Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise ValueError(f"cannot read map {str(path)!r}: {error.strerror}") from None
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not a YAML map (not UTF-8 text: byte {error.start})") from None
    except yaml.YAMLError as error:
        raise ValueError(f"{path}: not a YAML map ({_yaml_problem(error)})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a map must be a YAML mapping with image, resolution and "
                         f"origin, got {data!r}")
    extra = sorted(set(data) - _KEYS)
    if extra:
        raise ValueError(f"{path}: unknown key {extra[0]!r}; allowed: {sorted(_KEYS)}")
    for key in ("image", "resolution", "origin"):
        if key not in data:
            raise ValueError(f"{path}: missing {key!r}")
    if data.get("mode", "trinary") != "trinary":
        raise ValueError(f"{path}: mode must be 'trinary' (the only mode read), got "
                         f"{data['mode']!r}")
    resolution = _number(path, "resolution", data["resolution"])
    if resolution <= 0:
        raise ValueError(f"{path}: resolution must be > 0 (metres per pixel), got {resolution!r}")
    origin = data["origin"]
    if not (isinstance(origin, list) and len(origin) == 3):
        raise ValueError(f"{path}: origin must be [x, y, yaw] (metres, rad), got {origin!r}")
    x, y, yaw = (_number(path, f"origin[{i}]", v) for i, v in enumerate(origin))
    if yaw != 0:
        raise ValueError(f"{path}: origin yaw must be 0 (the map's rows along x), got {yaw!r}; "
                         "rotate the image instead")
    negate = data.get("negate", 0)
    if negate not in (0, 1) or isinstance(negate, bool):
        raise ValueError(f"{path}: negate must be 0 or 1, got {negate!r}")
    occupied_thresh = _number(path, "occupied_thresh", data.get("occupied_thresh", 0.65))
    free_thresh = _number(path, "free_thresh", data.get("free_thresh", 0.196))
    if not 0 <= free_thresh <= occupied_thresh <= 1:
        raise ValueError(f"{path}: thresholds need 0 <= free_thresh <= occupied_thresh <= 1, "
                         f"got free_thresh {free_thresh!r} and occupied_thresh "
                         f"{occupied_thresh!r}")
    occupancy = _occupancy(path, path.parent / str(data["image"]), negate)
    occupied = occupancy > occupied_thresh
    if unknown == "occupied":
        occupied |= occupancy >= free_thresh
    return OccupancyMap(occupied=occupied, resolution=100.0 * resolution,
                        origin=(100.0 * x, 100.0 * y), source=str(path))


def _yaml_problem(error) -> str:
    """PyYAML's error in one line: what it found, and where (lines and columns from 1), after
    what it was parsing and where that began."""
    def at(mark) -> str:
        return "" if mark is None else f" at line {mark.line + 1}, column {mark.column + 1}"
    problem = getattr(error, "problem", None)
    if problem is None:
        return str(error).splitlines()[0]
    context = getattr(error, "context", None)
    began = "" if context is None else f"{context}{at(getattr(error, 'context_mark', None))}: "
    return f"{began}{problem}{at(getattr(error, 'problem_mark', None))}"


def _number(path, key: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{path}: {key} must be a finite number, got {value!r}")
    return float(value)


def _occupancy(path, image_path: pathlib.Path, negate: int) -> np.ndarray:
    """Each pixel's occupancy in [0, 1], shape (rows, columns), as ``map_server`` computes it:
    its value over the image's full scale, 255, or 65535 for greyscale deeper than 8 bits
    (``_DEEP_GREY``)."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(image_path) as image:
            mode = image.mode
            deep = mode in _DEEP_GREY or (mode == "I" and image.format in _DEEP_GREY_AS_I)
            if mode in ("F", "I") and not deep:
                kind = {"F": "floating-point", "I": "32-bit integer"}[mode]
                raise ValueError(f"{path}: image {str(image_path)!r} holds {kind} pixels (mode "
                                 f"{mode!r}); save the map as 8- or 16-bit greyscale or as "
                                 "colour")
            full = 65535.0 if deep else 255.0
            pixels = np.asarray(image if deep or mode == "L" else image.convert("RGBA"),
                                dtype=np.float64)
    except FileNotFoundError:
        raise ValueError(f"{path}: image {str(image_path)!r} not found") from None
    except (OSError, UnidentifiedImageError) as error:
        raise ValueError(f"{path}: cannot read image {str(image_path)!r}: {error}") from None
    if pixels.ndim == 3:  # colour: the mean of the colour channels (alpha left out)
        pixels = pixels[..., :3].mean(axis=-1)
    if pixels.size == 0:
        raise ValueError(f"{path}: image {str(image_path)!r} is empty")
    return pixels / full if negate else (full - pixels) / full


def occupied_boxes(occupied: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Rectangles of cells ``(top, bottom, left, right)`` (rows top..bottom - 1, columns
    left..right - 1) that cover exactly the occupied cells, none overlapping: each row's runs
    of occupied cells, merged with the run spanning the same columns in the row above."""
    padded = np.pad(np.asarray(occupied, dtype=np.int8), ((0, 0), (1, 1)))
    open_runs: dict[tuple[int, int], int] = {}  # (left, right) -> top row
    boxes = []
    for row, cells in enumerate(padded):
        edges = np.flatnonzero(np.diff(cells))
        runs = {(int(left), int(right)) for left, right in zip(edges[::2], edges[1::2])}
        for run in list(open_runs):
            if run not in runs:
                boxes.append((open_runs.pop(run), row, *run))
        for run in runs:
            open_runs.setdefault(run, row)
    rows = len(padded)
    boxes.extend((top, rows, *run) for run, top in open_runs.items())
    return sorted(boxes)
