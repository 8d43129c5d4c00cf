"""Geometry: the shapes (one module each, switched over in shapes.py), the wide BVH's node layout
as kernels read it, traversal ray by ray and in packets, the two-level traversal of instances,
and the batch ray queries behind raylume.intersect."""
