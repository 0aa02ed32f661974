"""Search sizes the tests share: the same sizes compile the same programs, which the test
run's processes share through its compilation cache (tests/conftest.py)."""

SMALL = dict(n_particles=8, n_iters=12)  # where the point is behaviour, not search quality
