"""The model: the arm and its kinematics, the obstacle world, the polynomial joint paths
(paper eqs. 1-10), rigid-body dynamics, and the ``Problem`` that binds them.

Nothing here runs a collision check or an optimiser; everything above builds on it.
"""
