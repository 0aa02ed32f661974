"""The optimisers: the ask/tell protocol they share (``base``), PSO (``pso``) and evosax's
strategies (``evosax_adapter``) implementing it, the constraint rules that rank colliding paths
(``constraints``), the compiled loop that runs many restarts at once (``restarts``), the method
grammar and its parser (``methods``), and gradient ``refine``.

They see a problem only through ``jaxarm.checks.evaluate``; ``jaxarm.solve`` and the studies
sit on top.
"""
