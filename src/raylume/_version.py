"""The package's version, in a module of its own: cluster.py compares it with its workers'
without importing the package (which imports render.py, which leads back to the cluster)."""

__version__ = "0.1.0"
