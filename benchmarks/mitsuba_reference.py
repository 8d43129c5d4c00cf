"""The Mitsuba 3 reference for raylume's path tracer: the Cornell box, rendered independently.

tests/test_path_vs_mitsuba.py compares raylume's `mode = "path"` with the file this script
writes, tests/reference/cornell_mitsuba.npz, so CI never needs Mitsuba. Mitsuba is not a
raylume dependency; install it in a virtual environment of its own:

    python3.11 -m venv /work/mitsuba-venv
    /work/mitsuba-venv/bin/pip install mitsuba numpy scipy pytest
    # scipy and pytest: `control` imports the statistics of tests/test_path_vs_mitsuba.py

Commands (from the repository root; all but `geometry` need the Mitsuba venv):

    python benchmarks/mitsuba_reference.py geometry   # examples/cornell/*.obj from CORNELL below
    MI=/work/mitsuba-venv/bin/python
    $MI benchmarks/mitsuba_reference.py reference     # the stored reference (16 seeds x 4096 spp)
    $MI benchmarks/mitsuba_reference.py control       # Mitsuba vs Mitsuba: new seeds, and the
                                                      # light x 1.005 / a reflectance x 1.01
    $MI benchmarks/mitsuba_reference.py check         # the light's coverage against Mitsuba's image
    $MI benchmarks/mitsuba_reference.py preview       # PNGs to see the red wall on the left
    $MI benchmarks/mitsuba_reference.py timing        # samples per second, 1 and 2 threads

The scene is read from examples/cornell.toml (camera, materials, max_depth, objects) and built
for Mitsuba from the same OBJ files: one set of triangles for both renderers. The Cornell data
is right-handed (looking along +z with y up, +x is on the image's left: the red wall at
x ~ 550); the OBJ files hold it mirrored into raylume's left-handed frame (x' = 556 - x), and
Mitsuba loads them with a to_world that mirrors x back, so Mitsuba renders the original data.
Both images show the red wall on the left (`preview`, and `check` asserts it).

Mitsuba settings: variant scalar_rgb, integrator `path` (max_depth from the TOML, rr_depth 5,
its default), independent sampler, hdrfilm with a box reconstruction filter (samples uniform
over the pixel, as raylume's box filter), perspective sensor with fov_axis "y". Every BSDF is
wrapped in `twosided` (raylume's surfaces are two-sided). An emissive quad emits on both sides
in raylume; Mitsuba's area emitter emits on its front only, so an emissive quad becomes two
rectangles back to back, each facing one way and moved 0.005 mm along its own normal (the
light's upper face then sits 0.095 mm below the ceiling instead of 0.1 mm; by an estimate
(a Lambertian source under a plate: h/2 per unit of edge length escapes, times 1 + the ceiling's
reflectance) ~0.3% of the light's flux leaks out of that gap, so the 5% narrower gap changes the
image by ~0.015%, far below what the test resolves).

The pixels that see the light directly (any part of their square: the light's exact pixel
coverage, from projecting the quad and clipping it against each pixel) are left out of the
comparison: at its edges a pixel's value is mostly the chance that a sample lands on the light,
noise that would swamp the rest of a block. `check` verifies the coverage against Mitsuba: pixels the light covers
entirely are exactly its radiance; the test checks the same in raylume's image.

The stored reference: `reference` with its defaults, seeds 1..16 x 4096 spp at 64 x 64 (65536 spp
in the mean, 64 times the test's raylume budget), Mitsuba 3.9.1, 877 s on this project's 2 shared
cores; the image mean's relative standard error (light's pixels left out) is 1.1e-4 (R, G),
1.3e-4 (B). Control and sensitivity figures: tests/test_path_vs_mitsuba.py's docstring.

Mitsuba scalar_rgb speed on this scene (`timing`: 64 x 64, 256 spp, max_depth 8, the two-sided
light as two emitters), on the development machine's 2 vCPUs shared with other work, so rough:
1 thread 0.24-0.39 M samples/s, 2 threads 0.25-0.72 M samples/s (the low figures under a load
average of ~3; 0.39 and 0.72 at ~2.5).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import platform
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "examples" / "cornell.toml"
OBJ_DIR = REPO / "examples" / "cornell"
REFERENCE = REPO / "tests" / "reference" / "cornell_mitsuba.npz"
TEST_MODULE = REPO / "tests" / "test_path_vs_mitsuba.py"

MIRROR_X = 556.0  # x' = 556 - x maps the Cornell data into raylume's left-handed frame
EMITTER_OFFSET = 0.005  # mm: each face of a two-sided emitter is moved this far along its normal

# The measured Cornell box, in mm, right-handed (https://www.graphics.cornell.edu/online/box/data.html):
# quads in the data page's vertex order, each split into triangles (0, 1, 2) and (0, 2, 3).
# The light (343..213 x 227..332 at y = 548.8 on the page) is a quad object in the TOML, 0.1 mm
# below the ceiling at y = 548.7.
CORNELL = {
    "floor": [[(552.8, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 559.2), (549.6, 0.0, 559.2)]],
    "ceiling": [[(556.0, 548.8, 0.0), (556.0, 548.8, 559.2), (0.0, 548.8, 559.2), (0.0, 548.8, 0.0)]],
    "back_wall": [[(549.6, 0.0, 559.2), (0.0, 0.0, 559.2), (0.0, 548.8, 559.2), (556.0, 548.8, 559.2)]],
    "right_wall_green": [[(0.0, 0.0, 559.2), (0.0, 0.0, 0.0), (0.0, 548.8, 0.0), (0.0, 548.8, 559.2)]],
    "left_wall_red": [[(552.8, 0.0, 0.0), (549.6, 0.0, 559.2), (556.0, 548.8, 559.2), (556.0, 548.8, 0.0)]],
    "short_block": [
        [(130.0, 165.0, 65.0), (82.0, 165.0, 225.0), (240.0, 165.0, 272.0), (290.0, 165.0, 114.0)],
        [(290.0, 0.0, 114.0), (290.0, 165.0, 114.0), (240.0, 165.0, 272.0), (240.0, 0.0, 272.0)],
        [(130.0, 0.0, 65.0), (130.0, 165.0, 65.0), (290.0, 165.0, 114.0), (290.0, 0.0, 114.0)],
        [(82.0, 0.0, 225.0), (82.0, 165.0, 225.0), (130.0, 165.0, 65.0), (130.0, 0.0, 65.0)],
        [(240.0, 0.0, 272.0), (240.0, 165.0, 272.0), (82.0, 165.0, 225.0), (82.0, 0.0, 225.0)],
    ],
    "tall_block": [
        [(423.0, 330.0, 247.0), (265.0, 330.0, 296.0), (314.0, 330.0, 456.0), (472.0, 330.0, 406.0)],
        [(423.0, 0.0, 247.0), (423.0, 330.0, 247.0), (472.0, 330.0, 406.0), (472.0, 0.0, 406.0)],
        [(472.0, 0.0, 406.0), (472.0, 330.0, 406.0), (314.0, 330.0, 456.0), (314.0, 0.0, 456.0)],
        [(314.0, 0.0, 456.0), (314.0, 330.0, 456.0), (265.0, 330.0, 296.0), (265.0, 0.0, 296.0)],
        [(265.0, 0.0, 296.0), (265.0, 330.0, 296.0), (423.0, 330.0, 247.0), (423.0, 0.0, 247.0)],
    ],
}

# Reference and control configurations (64 x 64 pixels, 16 x 16 blocks: see the test).
REF_SEEDS = list(range(1, 17))  # 16 independent renders ...
REF_SPP = 4096  # ... of 4096 spp each: 65536 spp in the stored mean
CONTROL_SEED0 = 1000  # control renders use seeds from here on, never the reference's


# --------------------------------------------------------------------------- geometry


def write_geometry() -> None:
    """examples/cornell/<part>.obj: CORNELL mirrored into raylume's frame (x' = 556 - x), the
    winding reversed with it so each face keeps its side (both renderers are two-sided anyway)."""
    OBJ_DIR.mkdir(parents=True, exist_ok=True)
    for name, quads in CORNELL.items():
        lines = [
            f"# Cornell box, {name.replace('_', ' ')}: the measured data in mm",
            "# (graphics.cornell.edu/online/box/data.html), mirrored into raylume's",
            "# left-handed frame: x = 556 - x_cornell.",
            "# Written by benchmarks/mitsuba_reference.py geometry.",
        ]
        faces = []
        for q, quad in enumerate(quads):
            for x, y, z in quad:
                lines.append(f"v {_num(MIRROR_X - x)} {_num(y)} {_num(z)}")
            b = 4 * q + 1  # OBJ indices start at 1
            faces += [f"f {b} {b + 2} {b + 1}", f"f {b} {b + 3} {b + 2}"]  # (0,1,2), (0,2,3) reversed
        (OBJ_DIR / f"{name}.obj").write_text("\n".join(lines + faces) + "\n")
        print(f"wrote {OBJ_DIR / name}.obj ({2 * len(quads)} triangles)")


def _num(v: float) -> str:
    return f"{round(v, 4):.4f}".rstrip("0").rstrip(".")


# --------------------------------------------------------------------------- the scene


def load_toml(path: Path = SCENE) -> dict:
    with open(path, "rb") as f:
        return tomllib.load(f)


def test_module():
    """tests/test_path_vs_mitsuba.py: its scene digest and statistics are the ones used here."""
    spec = importlib.util.spec_from_file_location("test_path_vs_mitsuba", TEST_MODULE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look themselves up there
    spec.loader.exec_module(module)
    return module


def camera_frame(cam: dict):
    """raylume's camera (DESIGN.md section 3): position, forward, right, up, tan(fov/2)."""
    p = np.array(cam["position"], float)
    f = np.array(cam["look_at"], float) - p
    f /= np.linalg.norm(f)
    r = np.cross(np.array(cam.get("up", [0, 1, 0]), float), f)
    r /= np.linalg.norm(r)
    u = np.cross(f, r)
    return p, f, r, u, math.tan(math.radians(cam["fov"]) / 2)


def to_mitsuba_point(p) -> list[float]:
    return [MIRROR_X - p[0], p[1], p[2]]


def to_mitsuba_vector(v) -> list[float]:
    return [-v[0], v[1], v[2]]


def emissive_quads(doc: dict, light_scale: float = 1.0):
    """(corners in raylume's frame (4, 3), emission (3,)) of every emissive quad object."""
    out = []
    for obj in doc["objects"]:
        mat = doc["materials"][obj["material"]]
        if obj["type"] == "quad" and any(mat.get("emission", [0, 0, 0])):
            c, u, v = (np.array(obj[k], float) for k in ("position", "u", "v"))
            corners = np.array([c - u / 2 - v / 2, c + u / 2 - v / 2, c + u / 2 + v / 2, c - u / 2 + v / 2])
            out.append((corners, np.array(mat["emission"], float) * light_scale))
    return out


def mitsuba_dict(doc: dict, width: int, height: int, light_scale=1.0, reflectance=None):
    """The Mitsuba scene dictionary of the TOML document `doc` (only what the Cornell box uses:
    diffuse materials with optional emission, mesh and quad objects). `reflectance` scales
    named materials' colours ({name: factor}) for the sensitivity check."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    mirror = T().translate([MIRROR_X, 0, 0]).scale([-1, 1, 1])
    reflectance = reflectance or {}
    unknown = set(doc) - {"render", "camera", "materials", "objects"}
    if unknown or doc.get("lights"):
        raise SystemExit(f"mitsuba_reference: the scene has tables this translator does not know: {unknown}")

    cam = doc["camera"]
    p, f, _, up, _ = camera_frame(cam)
    scene = {
        "type": "scene",
        "integrator": {
            "type": "path",
            "max_depth": int(doc["render"]["max_depth"]),
            "rr_depth": 5,
        },
        "sensor": {
            "type": "perspective",
            "fov": float(cam["fov"]),
            "fov_axis": "y",
            "near_clip": 1.0,
            "far_clip": 100000.0,
            "to_world": T().look_at(
                origin=to_mitsuba_point(p),
                target=to_mitsuba_point(p + f),
                up=to_mitsuba_vector(up),
            ),
            "sampler": {"type": "independent", "sample_count": 1},
            "film": {
                "type": "hdrfilm",
                "width": width,
                "height": height,
                "pixel_format": "rgb",
                "component_format": "float32",
                "rfilter": {"type": "box"},
            },
        },
    }

    def bsdf(name):
        mat = doc["materials"][name]
        if mat.get("type") != "diffuse":
            raise SystemExit(f"mitsuba_reference: material {name!r} is not diffuse")
        colour = [c * reflectance.get(name, 1.0) for c in mat["color"]]
        return {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": colour}}}

    for i, obj in enumerate(doc["objects"]):
        mat = doc["materials"][obj["material"]]
        emission = [e * light_scale for e in mat.get("emission", [0, 0, 0])]
        if obj["type"] == "mesh":
            if any(k in obj for k in ("transform", "handedness", "instances")) or any(emission):
                raise SystemExit(f"mitsuba_reference: objects[{i}] uses keys this translator does not know")
            scene[f"object_{i}"] = {
                "type": "obj",
                "filename": str((SCENE.parent / obj["file"]).resolve()),
                "face_normals": True,  # flat triangles, as raylume's (the files have no normals)
                "to_world": mirror,
                "bsdf": bsdf(obj["material"]),
            }
        elif obj["type"] == "quad" and "transform" not in obj:
            c = np.array(to_mitsuba_point(obj["position"]), float)
            u = np.array(to_mitsuba_vector(obj["u"]), float)
            v = np.array(to_mitsuba_vector(obj["v"]), float)
            n = np.cross(u, v)
            n /= np.linalg.norm(n)
            # a rectangle is [-1, 1]^2 at z = 0 with normal +z; columns u/2, v/2, +-n map it here,
            # and its normal (the emitter's front) follows the third column
            sides = [1.0, -1.0] if any(emission) else [1.0]
            for side in sides:
                centre = c + side * n * EMITTER_OFFSET if any(emission) else c
                m = np.eye(4)
                m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = u / 2, v / 2, side * n, centre
                shape = {"type": "rectangle", "to_world": T(m.tolist()), "bsdf": bsdf(obj["material"])}
                if any(emission):
                    shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": emission}}
                scene[f"object_{i}_{'front' if side > 0 else 'back'}"] = shape
        else:
            raise SystemExit(f"mitsuba_reference: objects[{i}] of type {obj['type']!r} is not supported here")
    return scene


# --------------------------------------------------------------------------- exact light coverage


def _clip(poly: list, axis: int, bound: float, keep_above: bool) -> list:
    """Sutherland-Hodgman: the part of a convex polygon on one side of x[axis] = bound."""
    out = []
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        ina = (a[axis] >= bound) if keep_above else (a[axis] <= bound)
        inb = (b[axis] >= bound) if keep_above else (b[axis] <= bound)
        if ina:
            out.append(a)
        if ina != inb:
            t = (bound - a[axis]) / (b[axis] - a[axis])
            out.append((a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])))
    return out


def _area(poly: list) -> float:
    return 0.5 * abs(sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(poly, poly[1:] + poly[:1])))


def coverage(doc: dict, corners: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W) fraction of each pixel's square whose camera rays hit the quad with these corners
    (raylume's frame), by projecting it (a pinhole maps the planar quad to a quad) and clipping.
    Assumes nothing lies between the camera and the quad (`check` verifies it for the light)."""
    p, f, r, u, h = camera_frame(doc["camera"])
    w = h * width / height
    d = corners - p
    z = d @ f
    if np.any(z <= 0):
        raise SystemExit("mitsuba_reference: an emitter is partly behind the camera")
    a = (d @ r) / (z * w)
    b = (d @ u) / (z * h)
    poly = list(zip((a + 1) / 2 * width, (1 - b) / 2 * height))  # continuous pixel coordinates
    cov = np.zeros((height, width))
    xs, ys = [q[0] for q in poly], [q[1] for q in poly]
    for j in range(max(0, int(min(ys))), min(height, int(max(ys)) + 1)):
        for i in range(max(0, int(min(xs))), min(width, int(max(xs)) + 1)):
            piece = poly
            for axis, bound, above in ((0, i, True), (0, i + 1, False), (1, j, True), (1, j + 1, False)):
                piece = _clip(piece, axis, bound, above)
                if not piece:
                    break
            cov[j, i] = _area(piece) if len(piece) >= 3 else 0.0
    return cov


def light_coverage(doc: dict, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) coverage of the emissive quads together, and (H, W, 3) the radiance they add."""
    cov = np.zeros((height, width))
    radiance = np.zeros((height, width, 3))
    for corners, emission in emissive_quads(doc):
        c = coverage(doc, corners, width, height)
        cov += c
        radiance += c[:, :, None] * emission
    return cov, radiance


# --------------------------------------------------------------------------- rendering


class Renderer:
    """Mitsuba renders of the TOML scene at one size; `image(seed, spp)` is float64 (H, W, 3)."""

    def __init__(self, doc, width, height, light_scale=1.0, reflectance=None, threads=None):
        import drjit as dr
        import mitsuba as mi

        mi.set_variant("scalar_rgb")
        if threads:
            dr.set_thread_count(threads)
        self.mi = mi
        self.scene = mi.load_dict(mitsuba_dict(doc, width, height, light_scale, reflectance))

    def image(self, seed: int, spp: int) -> np.ndarray:
        return np.array(self.mi.render(self.scene, seed=seed, spp=spp), dtype=np.float64)[:, :, :3]


def render_seeds(renderer: Renderer, seeds, spp, label=""):
    """(S, H, W, 3) images of these seeds, and the seconds they took."""
    images, start = [], time.perf_counter()
    for k, seed in enumerate(seeds):
        images.append(renderer.image(seed, spp))
        if label:
            print(f"  {label} seed {seed} ({k + 1}/{len(seeds)}): {time.perf_counter() - start:.1f} s", flush=True)
    return np.stack(images), time.perf_counter() - start


def make_reference(args) -> None:
    import mitsuba as mi

    stats = test_module()
    doc = load_toml()
    W = H = stats.SIZE
    cov, _ = light_coverage(doc, W, H)
    mask = cov > 0  # left out of the statistics
    renderer = Renderer(doc, W, H, threads=args.threads)
    print(f"Mitsuba {mi.__version__} scalar_rgb: {len(args.seeds)} seeds x {args.spp} spp at {W}x{H}", flush=True)
    images, seconds = render_seeds(renderer, args.seeds, args.spp, "reference")
    blocks, globals_ = stats.masked_means(images, mask)
    meta = {
        "what": "Cornell box (examples/cornell.toml) rendered by Mitsuba 3; see benchmarks/mitsuba_reference.py",
        "width": W,
        "height": H,
        "block": stats.BLOCK,
        "spp_per_seed": args.spp,
        "seeds": list(args.seeds),
        "max_depth": int(doc["render"]["max_depth"]),
        "rr_depth": 5,
        "integrator": "path",
        "sampler": "independent",
        "rfilter": "box",
        "variant": "scalar_rgb",
        "statistics": "seed_block_means and seed_global_means leave out the pixels with light_coverage > 0",
        "mitsuba_version": mi.__version__,
        "python": platform.python_version(),
        "scene_digest": stats.scene_digest(SCENE),
        "render_seconds": round(seconds, 1),
        "threads": args.threads,
        "date": time.strftime("%Y-%m-%d"),
    }
    REFERENCE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        REFERENCE,
        mean=images.mean(axis=0).astype(np.float32),
        seed_block_means=blocks.astype(np.float32),
        seed_global_means=globals_.astype(np.float32),
        light_coverage=cov.astype(np.float32),
        meta=np.array(json.dumps(meta)),
    )
    se = globals_.std(axis=0, ddof=1) / math.sqrt(len(args.seeds))
    print(f"wrote {REFERENCE} ({REFERENCE.stat().st_size / 1024:.0f} KiB) in {seconds:.0f} s")
    print(f"image mean (light's pixels left out) {globals_.mean(axis=0)} +- {se} ({se / globals_.mean(axis=0)})")


# --------------------------------------------------------------------------- checks


def control(args) -> None:
    """Mitsuba against the stored reference with the test's statistics and its budget of
    seeds x spp: new seeds (must pass), and changed scenes (must fail)."""
    stats = test_module()
    doc = load_toml()
    ref = stats.load_reference(REFERENCE)
    W = H = stats.SIZE
    mask = ref.light_coverage > 0
    cases = [("control: new seeds", {})]
    if not args.only_control:
        cases += [
            ("light x 1.005", {"light_scale": 1.005}),
            ("white reflectance x 1.01", {"reflectance": {"white": 1.01}}),
            ("red reflectance x 1.01", {"reflectance": {"red": 1.01}}),
            ("green reflectance x 1.01", {"reflectance": {"green": 1.01}}),
        ]
    seed = CONTROL_SEED0
    for label, change in cases:
        renderer = Renderer(doc, W, H, threads=args.threads, **change)
        for trial in range(args.trials):
            seeds = list(range(seed, seed + args.seeds))
            seed += args.seeds
            images, seconds = render_seeds(renderer, seeds, args.spp)
            result = stats.compare(ref, *stats.masked_means(images, mask))
            print(
                f"{label:26s} trial {trial}: {'pass' if result.passed else 'FAIL'}  "
                f"image-mean z {np.array2string(result.z_global, precision=2)} "
                f"(limit {result.limit_global.min():.2f})  "
                f"block z: sd {result.z_blocks.std():.2f}, max |z| {np.abs(result.z_blocks).max():.2f} "
                f"(limit {result.limit_blocks.min():.2f}, "
                f"dof >= {result.dof_min:.0f})  [{seconds:.0f} s]",
                flush=True,
            )


def check(args) -> None:
    """The light's exact coverage against Mitsuba's image, and the red wall on the left."""
    stats = test_module()
    doc = load_toml()
    W = H = stats.SIZE
    cov, radiance = light_coverage(doc, W, H)
    images, _ = render_seeds(Renderer(doc, W, H, threads=args.threads), range(500, 500 + args.seeds), args.spp)
    mean = images.mean(axis=0)
    full = cov > 1 - 1e-9
    err = np.abs(mean[full] - radiance[full]).max()
    print(f"{full.sum()} pixels fully covered by the light: max |Mitsuba - emission| = {err:.2e}")
    assert full.sum() > 0 and err < 1e-4 * radiance.max()
    part = (cov > 0) & ~full
    # the ceiling around the light, per seed: positive in expectation, but a small budget's noise
    # can hide it, so it is judged against its standard error over the seeds (3 of them either way)
    rests = (images[:, part] - radiance[part]).sum(axis=1)
    rest = rests.mean(axis=0)
    se = rests.std(axis=0, ddof=1) / math.sqrt(len(rests)) if len(rests) > 1 else np.full(3, np.inf)
    print(
        f"{part.sum()} partly covered pixels: sum(Mitsuba - emission x coverage) = {rest} +- {se} "
        "(the ceiling around it)"
    )
    assert not np.any(rest + 3 * se < 0), "the partly covered pixels hold less than the light's share of them"
    inconclusive = bool(np.any(rest - 3 * se <= 0))
    if inconclusive:
        print(f"inconclusive at --seeds {args.seeds} --spp {args.spp}: within 3 standard errors of 0 (raise them)")
    ring = (np.abs(np.gradient(cov.astype(float))[0]) + np.abs(np.gradient(cov.astype(float))[1]) > 0) & (cov == 0)
    print(f"pixels next to the light, uncovered: mean {mean[ring].mean(axis=0)}; covered: {mean[part].mean(axis=0)}")
    left, right = mean[H // 2, : W // 8].mean(axis=0), mean[H // 2, -W // 8 :].mean(axis=0)
    print(f"left edge rgb {left}, right edge rgb {right}")
    assert left[0] > 2 * left[1] and right[1] > 2 * right[0], "the red wall must be on the left, green on the right"
    print("red wall on the left, green on the right: ok")
    if inconclusive:
        raise SystemExit("the ceiling's share of the partly covered pixels was inconclusive (above)")


def preview(args) -> None:
    import mitsuba as mi

    doc = load_toml()
    r = Renderer(doc, args.size, args.size, threads=args.threads)
    img = r.image(7, args.spp).astype(np.float32)
    out = Path(args.out)
    mi.util.write_bitmap(str(out), mi.Bitmap(img))
    print(f"wrote {out}")


def timing(args) -> None:
    import mitsuba as mi

    stats = test_module()
    doc = load_toml()
    W = H = stats.SIZE
    print(f"Mitsuba {mi.__version__} scalar_rgb, Cornell box {W}x{H}, path max_depth {doc['render']['max_depth']}")
    for threads in (1, 2):
        r = Renderer(doc, W, H, threads=threads)
        r.image(1, 4)  # warm-up
        times = []
        for rep in range(args.repeats):
            t = time.perf_counter()
            r.image(100 + rep, args.spp)
            times.append(time.perf_counter() - t)
        t = float(np.median(times))
        n = W * H * args.spp
        print(
            f"  {threads} thread(s): {args.spp} spp in {t:.2f} s (median of {args.repeats}): "
            f"{n / t / 1e6:.3f} M samples/s"
        )


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("geometry", help="write examples/cornell/*.obj")
    p = sub.add_parser("reference", help="render and store the reference")
    p.add_argument("--seeds", type=int, nargs="+", default=REF_SEEDS)
    p.add_argument("--spp", type=int, default=REF_SPP)
    p.add_argument("--threads", type=int, default=2)
    p = sub.add_parser("control", help="Mitsuba vs Mitsuba: control and sensitivity")
    p.add_argument("--seeds", type=int, default=None, help="renders per trial (default: the test's)")
    p.add_argument("--spp", type=int, default=None, help="spp per render (default: the test's)")
    p.add_argument("--trials", type=int, default=3)
    p.add_argument("--only-control", action="store_true")
    p.add_argument("--threads", type=int, default=2)
    p = sub.add_parser("check", help="the light's exact coverage against Mitsuba; red wall on the left")
    p.add_argument("--seeds", type=int, default=16)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--threads", type=int, default=2)
    p = sub.add_parser("preview", help="a PNG of Mitsuba's render")
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--out", default="cornell_mitsuba.png")
    p.add_argument("--threads", type=int, default=2)
    p = sub.add_parser("timing", help="Mitsuba samples per second, 1 and 2 threads")
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    if args.command == "control":
        stats = test_module()
        args.seeds = args.seeds or stats.SEEDS_N
        args.spp = args.spp or stats.SPP
    commands = {
        "geometry": lambda _: write_geometry(),
        "reference": make_reference,
        "control": control,
        "check": check,
        "preview": preview,
        "timing": timing,
    }
    commands[args.command](args)


if __name__ == "__main__":
    from common import run_main  # (here: tests import this module for its scene conversion)

    run_main(main)
