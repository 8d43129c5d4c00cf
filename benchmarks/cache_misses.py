"""Where a large mesh's frame waits for memory: the cache lines its camera rays miss.

The camera hit rays of bench_hits.py's frame (1024 x 1024, pixel order) are traced one by one
through a copy of the single-ray closest-hit loop (kernels/geometry/traverse.py `_bvh_hit`, built from
the same helpers: box test and sorted push, pop, leaf test) that logs every node record and
every leaf's triangle rows it reads. The log is then replayed through simulated caches (LRU,
16-way set-associative, 64-byte lines; hardware prefetchers not modelled), one size at a time,
and the misses are counted a ray: the lines missed, and the visits that missed at least one
line (each such visit waits for memory once at least, as nothing prefetches it far enough
ahead). `--node-bytes 128` replays the same visits with node records of half the size, as
quantized child boxes (Embree's compressed nodes) would make them; `--neighbours 4` with the
lines beside each leaf prefetched, as the traversal does on large meshes
(traverse.prefetch_neighbours).

On bumpy 4M the misses are compulsory: a cache of 32 MB misses as many lines as one of 512 KB
(every hit ray reads triangles no ray before it read; 10 triangles lie under each pixel).
A diagnostic, not a benchmark against peers: it measures no time.

    python benchmarks/cache_misses.py [--size 1024] [--node-bytes 256] [--neighbours 0] [--latency] [MESH ...]

`--latency` adds what a miss costs on this machine: a pointer chase (each load waits for the
one before) over 0.25 to 256 MB.
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np
from bench_hits import frame_rays, mesh
from common import run_main, table

from raylume.accel.wide import NODE_ROWS
from raylume.kernels.geometry import traverse
from raylume.kernels.geometry.shape_triangle import ray_shear
from raylume.kernels.geometry.wide_nodes import BVH_WIDTH, leaf_count, leaf_first, traversal_stacks
from raylume.kernels.scene import geometry_of

NODE, LEAF = 0, 1
CACHES_KB = (512, 4096, 32768)  # this VM's L2 a core, and two L3 sizes
LINE = 64
WAYS = 16


@numba.njit(cache=True)
def log_reads(G, O, D, log, node_stack, t_stack):
    """The single-ray closest-hit loop of kernels/geometry/traverse.py (no planes or instances, rows in
    leaf order), logging (NODE, node, 0) at each node visit and (LEAF, first row, rows) at each
    leaf; returns the number of entries."""
    index, bounds, tri = G.node_index, G.node_bounds, G.triangles
    n = 0
    for r in range(O.shape[0]):
        o = (O[r, 0], O[r, 1], O[r, 2])
        d = (D[r, 0], D[r, 1], D[r, 2])
        shear = ray_shear(d)
        rf, rows = traverse.box_ray(o, d)
        best_t, prim, b1, b2 = np.inf, np.int64(-1), 0.0, 0.0
        ref, top = 0, 0
        while True:
            if ref >= 0:
                log[n, 0], log[n, 1], log[n, 2] = NODE, ref, 0
                n += 1
                k, nearest = traverse.push_children(
                    bounds, index, G.prims, ref, rf, rows, best_t, node_stack, t_stack, top, tri, True
                )
                if k > 0:
                    top += k - 1
                    ref = nearest
                    continue
            else:
                first, count = leaf_first(ref), leaf_count(ref)
                log[n, 0], log[n, 1], log[n, 2] = LEAF, first, abs(count)
                n += 1
                best_t, prim, b1, b2 = traverse.intersect_leaf(
                    G, None, first, count, o, d, shear, 1e-9, best_t, prim, b1, b2, False
                )
            found, top, ref = traverse.pop_nearer(node_stack, t_stack, top, 0, best_t)
            if not found:
                break
    return n


@numba.njit(cache=True)
def lines_read(log, layout):
    """Every line the log reads, in order, with its kind."""
    n = 0
    for e in range(log.shape[0]):
        lo, hi = _span(log, e, layout)
        n += hi // LINE - lo // LINE + 1
    lines = np.empty(n, np.int64)
    kinds = np.empty(n, np.int64)
    n = 0
    for e in range(log.shape[0]):
        lo, hi = _span(log, e, layout)
        for line in range(lo // LINE, hi // LINE + 1):
            lines[n], kinds[n] = line, log[e, 0]
            n += 1
    return lines, kinds


@numba.njit(inline="always")
def _span(log, e, layout):
    """The first and last byte a log entry reads; layout: (bytes a node record, the triangle
    table's first byte, bytes a triangle row)."""
    node_bytes, tri_base, row_bytes = layout
    if log[e, 0] == NODE:
        lo = log[e, 1] * node_bytes
        return lo, lo + node_bytes - 1
    lo = tri_base + log[e, 1] * row_bytes
    return lo, lo + log[e, 2] * row_bytes - 1


@numba.njit(cache=True)
def replay(log, layout, cache_lines, neighbours):
    """Replays the log through an LRU cache of cache_lines lines (WAYS-way set-associative):
    (lines missed, visits with a miss), each per kind (NODE, LEAF). With `neighbours`, each leaf
    visit also brings in the lines traverse.prefetch_around prefetches (that many before its
    first row's first byte and from the byte after its rows on), counted as no miss: they
    serve later visits."""
    sets = cache_lines // WAYS
    tags = np.full((sets, WAYS), -1, np.int64)
    stamp = np.zeros((sets, WAYS), np.int64)
    missed = np.zeros(2, np.int64)
    visits_missed = np.zeros(2, np.int64)
    clock = 0
    for e in range(log.shape[0]):
        kind = log[e, 0]
        lo, hi = _span(log, e, layout)
        any_miss = False
        for line in range(lo // LINE, hi // LINE + 1):
            clock += 1
            if not _touch(tags, stamp, line, clock):
                missed[kind] += 1
                any_miss = True
        if any_miss:
            visits_missed[kind] += 1
        if kind == LEAF:
            for j in range(neighbours):
                clock += 1
                _touch(tags, stamp, (lo - LINE * (j + 1)) // LINE, clock)
                clock += 1
                _touch(tags, stamp, (hi + 1 + LINE * j) // LINE, clock)
    return missed, visits_missed


@numba.njit(inline="always")
def _touch(tags, stamp, line, clock):
    """Reads `line` through the cache: whether it was there (else it replaces its set's least
    recently used line)."""
    s = line % tags.shape[0]
    way = -1
    oldest = 0
    for w in range(WAYS):
        if tags[s, w] == line:
            way = w
            break
        if stamp[s, w] < stamp[s, oldest]:
            oldest = w
    found = way >= 0
    if not found:
        way = oldest
        tags[s, way] = line
    stamp[s, way] = clock
    return found


@numba.njit(cache=True)
def _chase(following, steps):
    i = 0
    for _ in range(steps):
        i = following[i]
    return i


def load_latency(megabytes: float, steps: int = 2_000_000) -> float:
    """Nanoseconds a load takes when each waits for the one before (a pointer chase over one
    random cycle through the lines of `megabytes`): what a miss costs at that size."""
    lines = int(megabytes * 1e6) // LINE
    order = np.random.default_rng(0).permutation(lines)
    following = np.zeros(lines * (LINE // 8), np.int64)  # one int64 read a line
    following[order * (LINE // 8)] = np.roll(order, -1) * (LINE // 8)
    _chase(following, 1000)
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        _chase(following, steps)
        best = min(best, time.perf_counter() - t0)
    return best / steps * 1e9


def per_ray(counts, rays):
    """Table cells: the NODE and LEAF counts, each a ray."""
    return [f"{counts[NODE] / rays:.2f}", f"{counts[LEAF] / rays:.2f}"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--node-bytes", type=int, default=NODE_ROWS * BVH_WIDTH * 4)
    ap.add_argument("--neighbours", type=int, default=0, help="lines prefetched on either side of each leaf")
    ap.add_argument("meshes", nargs="*", default=["40k", "4M"])
    ap.add_argument("--latency", action="store_true", help="also time a dependent load at 0.25 to 256 MB")
    args = ap.parse_args()
    numba.set_num_threads(1)
    rows = []
    for name in args.meshes:
        vf = mesh(name)
        if vf is None:
            print(f"{name}: not found, skipped")
            continue
        compiled, o, d, hit = frame_rays(*vf, args.size)
        G = geometry_of(compiled.kernel)
        O, D = np.ascontiguousarray(o[hit]), np.ascontiguousarray(d[hit])
        log = np.empty((O.shape[0] * 64, 3), np.int64)
        node_stack, t_stack = traversal_stacks()
        log = log[: log_reads(G, O, D, log, node_stack, t_stack)]
        rays = O.shape[0]
        nodes = np.count_nonzero(log[:, 0] == NODE) / rays
        leaves = np.count_nonzero(log[:, 0] == LEAF) / rays
        # the triangle table after the nodes, a page apart
        tri_base = -(-G.node_index.shape[0] * args.node_bytes // 4096) * 4096 + 4096
        layout = (args.node_bytes, tri_base, G.triangles.strides[0])
        visits = [name, f"{rays:,}", f"{nodes:.2f}", f"{leaves:.2f}", f"{args.node_bytes}"]

        # an unbounded cache misses each line once: the compulsory misses
        lines, kinds = lines_read(log, layout)
        first = np.unique(lines, return_index=True)[1]
        compulsory = [np.count_nonzero(kinds[first] == k) for k in (NODE, LEAF)]
        rows.append([*visits, "", "unbounded", *per_ray(compulsory, rays), "", ""])
        for kb in CACHES_KB:
            missed, waits = replay(log, layout, kb * 1024 // LINE, args.neighbours)
            rows.append([*visits, f"{args.neighbours}", f"{kb:,} KB", *per_ray(missed, rays), *per_ray(waits, rays)])
    print(
        table(
            [
                "mesh",
                "hit rays",
                "node visits a ray",
                "leaf visits a ray",
                "node bytes",
                "neighbours",
                "cache",
                "node lines missed a ray",
                "leaf lines missed a ray",
                "node visits that miss a ray",
                "leaf visits that miss a ray",
            ],
            rows,
        )
    )
    if args.latency:
        sizes = (0.25, 4, 32, 256)
        print(
            table(["working set", "ns a dependent load"], [[f"{mb:g} MB", f"{load_latency(mb):.1f}"] for mb in sizes])
        )


if __name__ == "__main__":
    run_main(main)
