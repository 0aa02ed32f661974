"""How programs are compiled: jaxarm's ``jit`` (compiler options, stored programs), the
persistent compilation cache, and the padding that lets a few programs serve every batch size.

The lowest layer: it knows nothing of arms or obstacles.
"""
