"""Evaluation of paths: the paper's sampled collision check, the certified continuous check,
joint limits, and fitness / violation / ``certify`` over any batch (``evaluate``).

Built on ``jaxarm.model``; the optimisers in ``jaxarm.optim`` call ``evaluate`` inside their loops.
"""
