"""The optimisers: PSO as an ask/tell swarm, the constraint rules that rank colliding paths,
the compiled loop that runs many restarts at once, the evosax adapter, and gradient ``refine``.

They see a problem only through ``jaxarm.checks.evaluate``; ``jaxarm.solve`` and the studies
sit on top.
"""
