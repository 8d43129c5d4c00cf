"""Hit rays against Embree: the issue-13 ratio, measured so that a busy machine does not decide it.

The camera rays of bench_bvh.py (DESIGN.md camera, pixel centres) that hit the mesh, traced by
raylume (`intersect_rays`, one thread: coherent rays in packets of eight, kernels/geometry/packet.py),
by raylume's single-ray traversal (`closest_hit` ray by ray, the same rays) and by Embree
three ways, single-threaded, all robust (watertight, as raylume): embreex's `run`
(`rtcIntersect1` ray by ray), `rtcIntersect1` called directly ("Embree 1", embree_direct.py)
and Embree's packets of eight consecutive rays, `rtcIntersect8` ("Embree 8", as raylume's
packets take them; embreex has no packet call). Each is timed in CPU time
(`time.process_time`), alternating them in one process. CPU time
leaves out the moments another process holds the core; alternation spreads the VM's drift over
the engines. The ratios are Embree's time over raylume's: above 1, raylume is faster. Beside
them, raylume's CPU time for the whole frame (all the camera rays, hits and misses), with
packets and with single rays (and through `raylume.intersect` itself, as a user calls it: the
directions made unit vectors in the kernel, the output arrays allocated; once with the rays in
a row, shape (N, 3), once as the image they are, shape (size, size, 3), which it traces in
packets of 4 x 2 pixels), and their ratios to bumpy 40k's: how the cost of a frame grows with
the triangle count, beside Embree's (a miss costs Embree more than raylume, so its frames grow
less in proportion). Last, the frame's cost with its data in cache: the frame's rays in
32 x 32 pixel blocks, each block traced twice in a row, less the same blocks traced once. The
repeat finds the block's nodes and triangles in cache (a block's ~1,000 rays touch well under
the L2's 2 MB), so what is left is the traversal's work without its waits for memory: how far
from 40k's a large mesh's frame would stay with memory free. After the table, each engine's hit
rays against bumpy 40k's: time / 40k's time (issue 49's scaling goal) and the time a ray added.

    python benchmarks/bench_hits.py [--size 1024] [--repeats 7] [--plot PNG] [MESH ...]

MESH: a name in ../shared/models (stanford-bunny, nefertiti) or a bumpy sphere's size (10k,
1M, 4M); by default the bunny, Nefertiti and bumpy 10k to 4M. `--plot` draws the bumpy spheres'
hit-ray times against their triangle counts (raylume's packets and single rays, Embree, and
issue 49's goal: Embree's time / 1.3).
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np
from bench_bvh import camera_rays, raylume_scene
from common import SHARED_MODELS, cached_entry, growth_table, machine, run_main, table
from embree_direct import EmbreeScene

import raylume
from raylume.kernels.geometry.query import CHUNK, intersect_singly
from raylume.kernels.geometry.wide_nodes import traversal_stacks
from raylume.kernels.scene import geometry_of
from raylume.kernels.variants import features
from raylume.kernels.vec import kernel_function
from raylume.query_lanes import intersect_rays
from raylume.scene.mesh import load_mesh
from raylume.scene.procedural import bumpy_sphere

DEFAULT = ["stanford-bunny", "nefertiti", "10k", "40k", "100k", "1M", "4M"]


def bumpy_size(name: str) -> int | None:
    """The triangle count a bumpy sphere's name says (10k, 1M), None for a shared model's name."""
    if name[-1] in "kM" and name[:-1].isdigit():
        return int(name[:-1]) * (1000 if name[-1] == "k" else 1_000_000)
    return None


def mesh(name: str):
    """(vertices, faces) of a shared model or of a bumpy sphere named by its size (10k, 1M)."""
    if (size := bumpy_size(name)) is not None:
        return bumpy_sphere(size)
    path = SHARED_MODELS / f"{name}.obj"
    if not path.exists():
        return None
    m = load_mesh(path)
    return m.vertices, m.faces


def frame_rays(vertices, faces, size):
    """The compiled scene, its camera rays and the mask of those that hit."""
    compiled = raylume_scene(vertices, faces)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    o, d = camera_rays((lo + hi) / 2, np.linalg.norm(hi - lo) / 2, size)
    t, *_ = _trace(compiled, o, d)
    return compiled, o, d, np.isfinite(t)


def block_orders(size: int, block: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """Ray indices of a row-major size x size frame in block x block pixel blocks, and the same
    with each block repeated at once."""
    y, x = np.mgrid[0:size, 0:size]
    per_row = -(-size // block)  # blocks across (the last may be partial)
    key = ((y // block) * per_row + x // block) * block * block + (y % block) * block + x % block
    blocks = np.argsort(key.ravel(), kind="stable")
    n = block * block
    twice = np.concatenate([np.concatenate([blocks[i : i + n]] * 2) for i in range(0, size * size, n)])
    return blocks, twice


def cpu_seconds(fn) -> float:
    c0 = time.process_time()
    fn()
    return time.process_time() - c0


def _trace(compiled, o, d):
    n = len(o)
    out = np.empty(n), np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.int32)
    intersect_rays(compiled.kernel, features(compiled.kernel), o, d, *out, 1)
    return out


@kernel_function
def _single_rays(S, X, o, d, spans, outputs, stacks, hits):
    """intersect_rays' work without packets: closest_hit ray by ray, a chunk at a time."""
    G = geometry_of(S)
    for start in range(0, o.shape[0], CHUNK):
        intersect_singly(G, X, o, d, spans, outputs, start, min(o.shape[0], start + CHUNK), stacks, hits)


single_rays = cached_entry(_single_rays)


def _trace_singly(compiled, o, d, stacks):
    n = len(o)
    out = np.empty(n), np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.int32)
    spans = np.zeros(1), np.full(1, np.inf)  # every ray from 0 to infinity
    hits = np.empty(CHUNK, np.int64), np.empty(CHUNK)
    single_rays(compiled.kernel, features(compiled.kernel), o, d, spans, out, stacks, hits)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("meshes", nargs="*", default=DEFAULT)
    parser.add_argument("--size", type=int, default=1024, help="image side: size x size camera rays")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--plot", default=None, help="write the bumpy spheres' hit-ray times (PNG) here")
    args = parser.parse_args()
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    numba.set_num_threads(1)
    stacks = traversal_stacks()
    print(f"hit rays of a {args.size} x {args.size} frame, 1 thread, CPU time, medians of {args.repeats}")
    print(f"alternating raylume and Embree; {machine()}\n")
    rows = []
    frame = {}  # CPU seconds of the whole frame, per mesh
    single_frame = {}  # the same with single rays
    embree_frame = {}  # the same by Embree
    in_cache = {}  # the frame with its data in cache (block_orders)
    hit_ms = {}  # per bumpy sphere: (triangles, raylume, single-ray, Embree) hit-ray ms
    hit_seconds, hit_rays = {}, {}  # per bumpy sphere: each engine's hit-ray seconds; the hit rays
    image_frame = {}  # raylume.intersect on the frame's rays as an image
    blocks, twice = block_orders(args.size)
    for name in args.meshes:
        vf = mesh(name)
        if vf is None:
            print(f"(skipping {name}: not found in {SHARED_MODELS})")
            continue
        v, f = vf
        compiled, fo, fd, hit = frame_rays(v, f, args.size)
        o, d = np.ascontiguousarray(fo[hit]), np.ascontiguousarray(fd[hit])
        bo, bd = np.ascontiguousarray(fo[blocks]), np.ascontiguousarray(fd[blocks])
        to, td = np.ascontiguousarray(fo[twice]), np.ascontiguousarray(fd[twice])
        embree = rtcs.EmbreeScene()
        TriangleMesh(embree, v.astype(np.float32), f.astype(np.int32))
        o32, d32 = o.astype(np.float32), d.astype(np.float32)
        fo32, fd32 = fo.astype(np.float32), fd.astype(np.float32)
        embree.run(o32[:1], d32[:1], output=1)  # Embree builds on the first query
        direct = EmbreeScene(v, f)
        for packets in (False, True):  # the direct calls answer as embreex's run
            assert np.array_equal(direct.intersect(o32, d32, packets)[2], embree.run(o32, d32))
        packed, single = _trace(compiled, o, d), _trace_singly(compiled, o, d, stacks)
        assert all(np.array_equal(a, b) for a, b in zip(packed[:2], single[:2], strict=True))  # t, object
        io, idir = fo.reshape(args.size, args.size, 3), fd.reshape(args.size, args.size, 3)  # the image
        in_rows, as_image = raylume.intersect(compiled, fo, fd), raylume.intersect(compiled, io, idir)
        assert all(np.array_equal(a, b.reshape(-1)) for a, b in zip(in_rows, as_image, strict=True))
        ours, singly, theirs, frames, single_frames, embree_frames, repeats = [], [], [], [], [], [], []
        api_frames, image_frames, ones, eights = [], [], [], []
        for _ in range(args.repeats):
            ours.append(cpu_seconds(lambda: _trace(compiled, o, d)))  # noqa: B023 (called at once)
            theirs.append(cpu_seconds(lambda: embree.run(o32, d32, output=1)))  # noqa: B023
            ones.append(cpu_seconds(lambda: direct.intersect(o32, d32)))  # noqa: B023
            eights.append(cpu_seconds(lambda: direct.intersect(o32, d32, packets=True)))  # noqa: B023
            singly.append(cpu_seconds(lambda: _trace_singly(compiled, o, d, stacks)))  # noqa: B023
            frames.append(cpu_seconds(lambda: _trace(compiled, fo, fd)))  # noqa: B023
            api_frames.append(cpu_seconds(lambda: raylume.intersect(compiled, fo, fd)))  # noqa: B023
            image_frames.append(cpu_seconds(lambda: raylume.intersect(compiled, io, idir)))  # noqa: B023
            single_frames.append(cpu_seconds(lambda: _trace_singly(compiled, fo, fd, stacks)))  # noqa: B023
            embree_frames.append(cpu_seconds(lambda: embree.run(fo32, fd32, output=1)))  # noqa: B023
            once = cpu_seconds(lambda: _trace(compiled, bo, bd))  # noqa: B023
            repeats.append(cpu_seconds(lambda: _trace(compiled, to, td)) - once)  # noqa: B023
        r, e, r1 = np.median(ours), np.median(theirs), np.median(singly)
        e1, e8 = np.median(ones), np.median(eights)
        frame[name] = np.median(frames)
        image_frame[name] = np.median(image_frames)
        single_frame[name] = np.median(single_frames)
        embree_frame[name] = np.median(embree_frames)
        in_cache[name] = np.median(repeats)
        pairs = np.array(theirs) / np.array(ours)
        if bumpy_size(name) is not None:
            hit_ms[name] = (len(f), r * 1e3, r1 * 1e3, e * 1e3, e1 * 1e3, e8 * 1e3)
            hit_seconds[name] = {"packets": r, "single rays": r1, "Embree": e, "Embree 1": e1, "Embree 8": e8}
            hit_rays[name] = len(o)
        rows.append(
            [name, f"{len(f):,}", f"{len(o):,}", f"{r * 1e3:.1f}", f"{r1 * 1e3:.1f}", f"{e * 1e3:.1f}", f"{e / r:.2f}"]
            + [f"{pairs.min():.2f}-{pairs.max():.2f}", f"{e / r1:.2f}"]
            + [f"{e1 * 1e3:.1f}", f"{e8 * 1e3:.1f}", f"{e1 / r:.2f}", f"{e8 / r:.2f}", f"{frame[name] * 1e3:.1f}"]
            + [f"{np.median(api_frames) * 1e3:.1f}", f"{image_frame[name] * 1e3:.1f}"]
            + [f"{single_frame[name] * 1e3:.1f}", f"{embree_frame[name] * 1e3:.1f}", f"{in_cache[name] * 1e3:.1f}"]
        )
        print(" | ".join(rows[-1]), flush=True)
    base, single_base = frame.get("40k"), single_frame.get("40k")
    for row in rows:
        row.append(f"{frame[row[0]] / base:.2f}" if base else "-")
        row.append(f"{image_frame[row[0]] / image_frame['40k']:.2f}" if base else "-")
        row.append(f"{single_frame[row[0]] / single_base:.2f}" if base else "-")
        row.append(f"{embree_frame[row[0]] / embree_frame['40k']:.2f}" if base else "-")
        row.append(f"{in_cache[row[0]] / in_cache['40k']:.2f}" if base else "-")
    headers = ["mesh", "triangles", "hit rays", "raylume ms", "single-ray ms", "Embree ms", "Embree / raylume"]
    headers += ["per pair", "Embree / single-ray", "Embree 1 ms", "Embree 8 ms", "Embree 1 / raylume"]
    headers += ["Embree 8 / raylume", "raylume frame ms", "raylume.intersect frame ms"]
    headers += ["raylume.intersect image ms", "single-ray frame ms", "Embree frame ms"]
    headers += ["in-cache frame ms", "frame / 40k frame", "image / 40k image", "single-ray frame / 40k"]
    headers += ["Embree frame / 40k"]
    headers += ["in-cache frame / 40k"]
    print("\n" + table(headers, rows))
    if grown := growth_table(hit_seconds, hit_rays):
        print("\nhit rays, growth from bumpy 40k:\n" + grown)
    if args.plot and hit_ms:
        plot_hits(hit_ms, args.size, args.plot)


def plot_hits(hit_ms: dict, size: int, path: str) -> None:
    """The bumpy spheres' hit-ray times against their triangle counts, log-log."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n, ours, single, _, one, eight = (np.array(c) for c in zip(*sorted(hit_ms.values()), strict=True))
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(n, ours, "o-", label="raylume (packets of 8 rays)")
    ax.plot(n, single, "s-", label="raylume, one ray at a time")
    ax.plot(n, one, "^-", color="black", label="Embree 4, one ray at a time (rtcIntersect1)")
    ax.plot(n, eight, "v--", color="black", label="Embree 4, packets of 8 rays (rtcIntersect8)")
    best = np.minimum(one, eight)
    ax.plot(n, best / 1.3, ":", color="grey", label="issue 49's goal: the faster Embree's time / 1.3")
    ax.set_xscale("log")
    ax.set_xlabel("triangles (bumpy sphere)")
    ax.set_ylabel(f"ms for the hit rays of a {size} x {size} frame")
    ax.set_ylim(bottom=0)
    ax.set_title("Camera hit rays, 1 thread (CPU time)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    print(f"wrote {path}")


if __name__ == "__main__":
    run_main(main)
