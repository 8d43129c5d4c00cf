"""The wide BVH's node record as kernels read it (accel/wide.py builds it): the rows of a node and
the leaf count's codes. Here, in the kernels, so that the kernel cache's key (kernels/__init__.py)
covers them: they are compiled into the machine code of every traversal."""

NODE_ROWS = 8  # rows of a node record: six planes, first, count
NODE_FIRST, NODE_COUNT = 6, 7

# A leaf's count field tells how traversal tests it: count > 0, primitives first .. first +
# count - 1 one by one; -4 .. -2, that many triangles at once (mark_triangle_leaves); below
# -SPHERE_BLOCK, -count - SPHERE_BLOCK spheres at once (mark_sphere_leaves).
SPHERE_BLOCK = 8
