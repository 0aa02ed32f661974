"""The paper's published numbers (Machmudah & Parman 2013), as data.

Every coefficient set is ``[a61, a62, a63]``; a fitness of 0 is the paper's verdict "collides".
These are what the shipped paper scenarios are reconstructed from and checked against
(``jaxarm.paper.reconstruct``), and what ``reproduce_paper`` compares with.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class PublishedSet(NamedTuple):
    """One published coefficient set: where it is printed, the set, the paper's fitness."""

    source: str  # e.g. "Table 2, A run 1, escaping"
    a6: tuple[float, float, float]
    fitness: float  # 0 means the paper found it colliding

    @property
    def feasible(self) -> bool:
        return self.fitness > 0


def a6_array(sets) -> np.ndarray:
    """The coefficient sets of ``sets`` as one array, shape (n_sets, 3), float64."""
    return np.array([s.a6 for s in sets], np.float64).reshape(-1, 3)


def _sets(source: str, rows) -> tuple[PublishedSet, ...]:
    return tuple(PublishedSet(f"{source}{label}", tuple(map(float, a6)), float(fitness))
                 for label, a6, fitness in rows)


# Case 1, Table 2: the escaping and the evolved (100 iterations) best of every escaped run.
# All are collision-free in the paper. C run 5's evolved a62 is printed +69.649, most likely a
# dropped minus sign (every other a62 is -60 to -74). Fitness cannot tell: f(a6) = f(-a6) for
# every joint (the a6 term of dtheta/dr is odd about r = 1/2, the rest even), so that row is kept
# apart and only its fitness is used.
CASE_1_END_POINTS = ((50.0, -10.0), (50.0, 40.0))  # end-effector start and goal, cm
CASE_1 = _sets("Table 2, ", [
    ("A run 1 escaping", [59.418, -63.667, 0.0], 0.1717),
    ("A run 1 evolved", [58.91, -63.237, -0.4425], 0.1724),
    ("A run 3 escaping", [57.396, -65.55, 10.886], 0.1695),
    ("A run 3 evolved", [52.461, -60.1392, 10.8932], 0.1774),
    ("A run 7 escaping", [82.7691, -71.535, -34.144], 0.1393),
    ("A run 7 evolved", [55.1786, -64.2508, 7.1811], 0.1732),
    ("B run 1 escaping", [86.4098, -71.8554, -44.7995], 0.1323),
    ("B run 1 evolved", [78.5906, -67.7068, -43.614], 0.1389),
    ("B run 3 escaping", [67.8054, -69.8544, -12.1606], 0.1589),
    ("B run 3 evolved", [66.985, -70.2461, -12.1546], 0.1592),
    ("B run 4 escaping", [85.0301, -73.5545, -37.2313], 0.1357),
    ("B run 4 evolved", [80.0597, -73.9362, -19.8461], 0.1458),
    ("C run 2 escaping", [80.0420, -66.9973, -41.2126], 0.1397),
    ("C run 2 evolved", [77.3644, -65.8755, -40.9938], 0.1419),
    ("C run 4 escaping", [86.7794, -65.8419, -65.4384], 0.1255),
    ("C run 4 evolved", [67.6419, -62.9829, -23.1282], 0.1589),
    ("C run 5 escaping", [70.377, -73.4002, -5.3923], 0.1565),
])
CASE_1_DOUBTFUL = PublishedSet("Table 2, C run 5 evolved (a62 printed +69.649)",
                               (70.644, 69.649, 9.8101), 0.158)
CASE_1_ESCAPES = {"A": 3, "B": 3, "C": 3}  # Table 2: escaped runs out of 7 per preset
CASE_1_RUNS = 7


class EscapedRun(NamedTuple):
    """One escaped run of Table 2: where it escaped and what it had evolved to by iteration 100."""

    preset: str  # "A", "B" or "C"
    run: int  # 1 .. 7
    escape_iter: int  # the first iteration with a collision-free particle
    escaping: PublishedSet  # the global best at that iteration
    evolved: PublishedSet  # the global best at iteration 100

    @property
    def gain(self) -> float:
        """Fitness gained between the escape and iteration 100."""
        return self.evolved.fitness - self.escaping.fitness


# Table 2's nine escaped runs (C run 5's evolved set is ``CASE_1_DOUBTFUL``; its fitness is
# printed as it is). Their gains: +0.0007, +0.0079, +0.0339 (A), +0.0066, +0.0003, +0.0101 (B),
# +0.0022, +0.0334, +0.0015 (C).
CASE_1_ESCAPED_RUNS = tuple(
    EscapedRun(preset, run, escape_iter, CASE_1[2 * i],
               CASE_1[2 * i + 1] if 2 * i + 1 < len(CASE_1) else CASE_1_DOUBTFUL)
    for i, (preset, run, escape_iter) in enumerate([
        ("A", 1, 48), ("A", 3, 24), ("A", 7, 19), ("B", 1, 29), ("B", 3, 87), ("B", 4, 8),
        ("C", 2, 32), ("C", 4, 39), ("C", 5, 94)]))

# Case II (Tables 3-6): every set the paper evaluated on it, with its verdict.
CASE_2_TABLE_3 = _sets("Table 3", [("", [66.7388, -28.1028, -9.8855], 0.1946)])
CASE_2_TABLE_4 = _sets("Table 4 ", [
    ("(1)", [113.0533, -42.3741, -10.0300], 0.1476),
    ("(2)", [147.7472, -70.80701, 48.89361], 0.10656),
    ("(3)", [124.1641, -53.39219, 9.386029], 0.13575),
    ("(4)", [119.2847, -80.32816, 41.86955], 0.11624),
    ("(5)", [181.0683, -34.8128, -147.858], 0.080496),
])
CASE_2_TABLE_5 = _sets("Table 5", [
    ("", [120, -50, -8], 0.14), ("", [120, -50, 20], 0), ("", [120, -40, 20], 0),
    ("", [120, -65, 0], 0.1335), ("", [140, -60, 40], 0), ("", [120, -50, 9.386029], 0.1397),
    ("", [120, -50, 12], 0.1391), ("", [120, -50, 16], 0.1380), ("", [120, -50, 17], 0),
    ("", [124.1641, -53.39, 17], 0.1338), ("", [124.1641, -53.39, 20], 0.1329),
    ("", [124.1641, -53.39, 21], 0.1325), ("", [124.1641, -53.39, 22], 0),
    ("", [113.05, -42.3741, 4], 0.1486), ("", [113.05, -42.3741, 5], 0),
])
CASE_2_TABLE_5_SWEEPS = (  # Table 5 remarks: base set, the paper's largest feasible a63
    ((120.0, -50.0, 0.0), 16.0), ((124.1641, -53.39219, 0.0), 21.0),
    ((113.0533, -42.3741, 0.0), 4.0),
)
CASE_2_TABLE_6 = (  # (initial particle, evolved best, its fitness)
    ((181.0683, -34.8128, -147.858), (62.9, -25.115, -15.554), 0.19765),
    ((119.2847, -80.32816, 41.86955), (63.934, -26.45, -13.261), 0.19707),
    ((66.7388, -28.1028, -9.8855), (61.51, -22.95, -18.847), 0.19819),
)
CASE_2 = (CASE_2_TABLE_3 + CASE_2_TABLE_4 + CASE_2_TABLE_5
          + _sets("Table 6 evolved ", [(f"({i + 1})", evolved, fitness)
                                       for i, (_, evolved, fitness) in enumerate(CASE_2_TABLE_6)]))

# Case III (Table 3): the best set after 100 generations.
CASE_3 = _sets("Table 3", [("", [3.4136, -139.7617, -0.2667], 0.0973)])
