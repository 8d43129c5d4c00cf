"""The wide BVH's node record as kernels read it (accel/wide.py builds it): the rows of a node and
how a lane's reference encodes a child. Here, in the kernels, so that the kernel cache's key
(kernels/__init__.py) covers them: they are compiled into the machine code of every traversal.

The functions are plain integer arithmetic, so they serve numpy arrays (accel/, compile/) and,
wrapped by wide_nodes.py, the kernels alike."""

NODE_ROWS = 7  # rows of a node record: six planes, then each lane's reference
NODE_REF = 6

# A lane's reference (int32): an inner child's node index (>= 0; 0 in an unused lane, the root
# being no one's child), or for a leaf ~(first << LEAF_SHIFT | count + LEAF_BIAS) (< 0): the
# leaf's first primitive and its count field in one row, so that a record is 224 bytes, not 256
# (issue 49's memory goal). The count field tells how traversal tests the leaf: count > 0,
# primitives first .. first + count - 1 one by one; -4 .. -2, that many triangles at once
# (mark_triangle_leaves); below -SPHERE_BLOCK, -count - SPHERE_BLOCK spheres at once
# (mark_sphere_leaves). Counts lie in LEAF_COUNTS, first primitives below LEAF_FIRST_LIMIT.
SPHERE_BLOCK = 8
LEAF_SHIFT = 5
LEAF_BIAS = 1 << (LEAF_SHIFT - 1)
LEAF_COUNTS = range(-LEAF_BIAS, LEAF_BIAS)  # -16 .. 15
LEAF_FIRST_LIMIT = 1 << (31 - LEAF_SHIFT)  # 2**26 primitives in one BVH


def leaf_ref(first, count):
    """The reference of a leaf of `count` (its count field) primitives from `first` on."""
    return ~((first << LEAF_SHIFT) | (count + LEAF_BIAS))


def leaf_first(ref):
    """A leaf reference's first primitive."""
    return ~ref >> LEAF_SHIFT


def leaf_count(ref):
    """A leaf reference's count field."""
    return (~ref & ((1 << LEAF_SHIFT) - 1)) - LEAF_BIAS


# Node records start on a cache line (accel/wide.py's node_records): a 224-byte record then
# spans four lines, where numpy's large arrays, 16 bytes into one, left half of them on five
# (benchmarks/ab_queries.py, pinned: bumpy 4M hit rays 0.9-1.2% faster, shadow rays 2.4%, 1M
# hit rays 1.4%, 40k the same).
RECORD_ALIGNMENT = 64


def line_aligned(shape, dtype):
    """An uninitialised C-contiguous numpy array whose first byte starts a cache line."""
    import numpy as np

    dtype = np.dtype(dtype)
    size = int(np.prod(shape)) * dtype.itemsize
    raw = np.empty(size + RECORD_ALIGNMENT, np.uint8)
    skip = -raw.ctypes.data % RECORD_ALIGNMENT
    return raw[skip : skip + size].view(dtype).reshape(shape)


def on_a_line(a):
    """The array a where its first byte starts a cache line, else a copy that does (records
    that come back from a pickle, on a cluster's worker)."""
    if a.ctypes.data % RECORD_ALIGNMENT == 0:
        return a
    out = line_aligned(a.shape, a.dtype)
    out[...] = a
    return out
