"""The annealed RMSProp-style grasp optimizer (optimization from scratch and post-optimization).

Importing the package is light (``optim.config`` is a leaf of the config tree): import the
optimizer from ``optim.annealing``, the start poses from ``optim.init``."""
