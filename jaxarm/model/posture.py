"""An arm at one posture against the world: how deep each link enters, how far each keeps.

Both give one value per link and obstacle slot; the checks fold them along a path's samples
(``jaxarm.checks``), and ``Problem`` uses them to reject a start or goal posture that collides.
"""

from __future__ import annotations

import jax.numpy as jnp

from jaxarm.model import world as world_lib
from jaxarm.model.arm import link_endpoints


def penetration(lengths, world, theta):
    """Penetration depth of every link into every obstacle slot.

    Args:
      lengths: link lengths, shape (n_joints,).
      world: ``WorldArrays``.
      theta: joint angles, shape (..., n_joints).

    Returns:
      Array of shape (..., n_joints, n_obstacle_slots), >= 0.
    """
    links = link_endpoints(lengths, theta)
    return jnp.stack([jnp.moveaxis(world_lib.overlap_depth_xy(*link, world), 0, -1)
                      for link in links], axis=-2)


def separation(lengths, world, theta):
    """Exact separation (cm) of every link from every obstacle slot at one posture.

    Args:
      lengths: link lengths, shape (n_joints,).
      world: ``WorldArrays``.
      theta: joint angles, shape (n_joints,).

    Returns:
      Array of shape (n_joints, n_obstacle_slots).
    """
    return jnp.stack([world_lib.separation_xy(*link, world)
                      for link in link_endpoints(lengths, list(theta))])
