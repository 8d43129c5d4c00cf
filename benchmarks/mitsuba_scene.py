"""A raylume scene of the kinds examples/materials.toml uses, as a Mitsuba 3 `load_dict` dictionary
that renders the same image (up to noise and the approximations listed below).

    python benchmarks/mitsuba_scene.py compare [SCENE] [--width 160 --height 80 --spp 64]
                                       [--variant scalar_rgb] [--out /tmp/materials_compare.png]

`compare` renders the scene with raylume (path mode) and with Mitsuba three ways, prints the
images' mean colours and the relative differences of block means (a downscaled difference image),
and writes a PNG, one row each: raylume | Mitsuba | |difference| x 4. The rows: (1) the glass's
absorption left out on both sides, (2) taken into account on both sides (Mitsuba's `volpath` with
a homogeneous absorbing medium inside the glass, raylume's own Beer-Lambert); (3) the scene as
bench_path.py times it: raylume's glass absorbs, Mitsuba's `path` ignores the absorption. Mitsuba:
pip install 'raylume[bench]'; its llvm_ad_rgb variant needs LLVM (on Debian: apt-get install
libllvm19).

What is translated (anything else raises SystemExit naming it):

- Frame: raylume is left-handed (DESIGN.md section 3), Mitsuba right-handed. Every point and
  vector is mirrored, (x, y, z) -> (-x, y, z) (M below), so Mitsuba renders the mirrored world
  through a mirrored camera: the same image, +x on the right as in raylume (mitsuba_reference.py
  does the same for the Cornell box, with x -> 556 - x).
- Camera: `perspective` (`thinlens` when aperture > 0) with raylume's vertical fov
  (fov_axis "y"), look_at built from raylume's position, look_at and orthogonalised up.
- Film: hdrfilm of the render size; rfilter as [render] filter says: box (raylume's default:
  samples uniform over the pixel), gaussian (stddev 0.5 as raylume's, but Mitsuba cuts it off at
  2 px, raylume at 1.5) or mitchell (B = C = 1/3).
- Integrator: `path` with the scene's max_depth (-1: unlimited), rr_depth 5 (raylume's RR_DEPTH),
  hide_emitters false (the environment is seen directly, as in raylume).
- Spheres: `sphere`. Planes: a `rectangle` of half-side PLANE_HALF_SIZE (10^4 scene units),
  centred under the camera; beyond it (0.01 degrees below the horizon from 1.6 units up) the
  environment shows where raylume's infinite plane would be.
- Materials: diffuse -> `diffuse`; conductor -> `conductor` / `roughconductor` (GGX, alpha =
  roughness, raylume's roughness is the GGX alpha) with eta and k (neither: material "none"),
  specular_reflectance = color; dielectric -> `dielectric` / `roughdielectric` (GGX), int_ior =
  ior, ext_ior 1, specular_transmittance = color; plastic -> `plastic` / `roughplastic` (GGX),
  diffuse_reflectance = color, int_ior = ior clamped to [1, 3] as raylume clamps it, nonlinear
  false. All but the dielectric are wrapped in `twosided`, as raylume's are two-sided.
- Checker textures (raylume: a 3D checkerboard in world space, cells of side `scale`,
  colors[0] where floor(x/s) + floor(y/s) + floor(z/s) is even) on an axis-aligned plane: a
  `checkerboard` on the rectangle's uv with to_uv = scale(half-side / s) (Mitsuba's cells are half
  a uv unit, its color0 where both halves agree), the rectangle centred on a multiple of 2 s and
  its half-side an even multiple of s, so the cells coincide exactly; the colours are swapped
  where the plane's constant coordinate falls in an odd cell. raylume filters the checker over
  each pixel's footprint (ray cones, texture_filter); Mitsuba point-samples it: the same image
  after the film's box filter, except aliasing near the horizon. A checker elsewhere (a sphere,
  a tilted plane) is approximated by the uv checkerboard and said so.
- Environment: `envmap` from the texels raylume itself loads (raylume.compile.environment's
  loader, not Mitsuba's .hdr reader, which decodes RGBE without Radiance's +0.5), scale =
  intensity, to_world = M R M where R is raylume's rotate (x, then y, then z): Mitsuba's envmap
  looks along +z at its centre column, +y at its top row and -x a quarter to the right, raylume's
  along +x, so in the mirrored frame they agree. Both look the texels up bilinearly, columns
  wrapping, with texel j's centre at u = (j + 0.5) / W; rows differ (below). A constant colour is a
  `constant` emitter.

Approximations, which `notes` lists for a given scene:

- Absorption inside a dielectric (raylume's Beer-Lambert `absorption`): Mitsuba's `path`
  integrator ignores media, so by default the glass is clear in Mitsuba (absorption="ignore").
  absorption="medium" gives the glass a homogeneous interior medium, sigma_t = absorption,
  albedo 0, and switches the integrator to `volpath`: the same expected image (free-flight
  sampling ends a path where raylume multiplies by exp(-sigma d)), but a different integrator, so
  only for checking images, not for timing.
- Planes: a finite rectangle (above). Checker: exact on axis-aligned planes (above).
- Environment rows: Mitsuba spreads an H-row image's rows from pole to pole (row i's value at
  theta = pi i / (H - 1), its first and last rows on the poles), raylume puts row i's centre at
  theta = pi (i + 0.5) / H and clamps within half a row of a pole. The two agree on the equator
  and drift apart towards the poles, by (v - 1/2) rows at v = theta / pi: a sky's gradient or a
  sharp edge between rows moves by up to half a row (0.7 degrees for examples/sky.hdr's 128 rows).
  Given raylume's H rows as they are, on examples/materials.toml this was the largest
  difference: the sun (rows 37-41 of 128, v ~ 0.3) sits 0.2 rows nearer the zenith in
  Mitsuba and each row spans pi / 127 instead of pi / 128, so the irradiance on the floor is 1.0,
  0.9 and 0.6 % (r, g, b) higher in Mitsuba (the quadrature of the two lookups; the floor away
  from the spheres measured the same to 0.03 %), the whole image 0.9, 0.8, 0.5 % brighter; the
  sky seen directly, near the horizon, differs by under 0.05 %. An image of 2 H + 1 rows,
  raylume's rows interleaved with the means of neighbouring rows and the first and last rows
  repeated on the poles, makes Mitsuba's lookup raylume's exactly (to float32 rounding: both are
  linear in v between the same knots), and then the floor agrees to 0.03 %: Mitsuba is given that
  image (pole_to_pole_rows).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
MATERIALS = REPO / "examples" / "materials.toml"

PLANE_HALF_SIZE = 1.0e4  # scene units; a multiple of 2 x the checker's cell keeps the cells aligned
MIRROR = np.diag([-1.0, 1.0, 1.0])  # raylume's left-handed frame <-> Mitsuba's right-handed one
PLASTIC_ETA_MAX = 3.0  # raylume clamps a plastic's index to [1, 3] (kernels/shading/materials/coating.py)


def to_mitsuba(v) -> list[float]:
    """A point or vector of raylume's frame in Mitsuba's (mirrored in x)."""
    return [float(-v[0]), float(v[1]), float(v[2])]


def camera_frame(cam):
    """raylume's camera (DESIGN.md section 3): position, forward, right, up (unit vectors)."""
    p = np.array(cam.position, float)
    f = np.array(cam.look_at, float) - p
    f /= np.linalg.norm(f)
    r = np.cross(np.array(cam.up, float), f)
    r /= np.linalg.norm(r)
    return p, f, r, np.cross(f, r)


def rotation(rotate) -> np.ndarray:
    """raylume's rotation of `rotate` = [x, y, z] degrees: Rz @ Ry @ Rx (scene/mesh.py's
    transform_matrix), written out here so that this file does not follow raylume's internals."""
    ax, ay, az = np.radians(np.asarray(rotate, float))
    (cx, sx), (cy, sy), (cz, sz) = ((math.cos(a), math.sin(a)) for a in (ax, ay, az))
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _matrix4(a3: np.ndarray, t=(0.0, 0.0, 0.0)) -> list[list[float]]:
    m = np.eye(4)
    m[:3, :3] = a3
    m[:3, 3] = t
    return m.tolist()


def _rgb(c) -> dict:
    return {"type": "rgb", "value": [float(x) for x in c]}


def load(path: str | Path = MATERIALS):
    import raylume

    return raylume.load_scene(path)


def pole_to_pole_rows(texels: np.ndarray) -> np.ndarray:
    """raylume's (H, W, 3) environment as the (2 H + 1, W, 3) image whose Mitsuba lookup (rows
    from pole to pole) is raylume's bilinear one: row 2 k + 1 is raylume's row k (its centre,
    theta = pi (k + 1/2) / H), row 2 k the mean of rows k - 1 and k (raylume's value halfway
    between their centres), and the first and last rows raylume's first and last (it clamps
    within half a row of a pole)."""
    h = texels.shape[0]
    out = np.empty((2 * h + 1, *texels.shape[1:]), dtype=np.float32)
    out[1::2] = texels
    out[2:-1:2] = (texels[:-1].astype(np.float64) + texels[1:]) / 2
    out[0], out[-1] = texels[0], texels[-1]
    return out


def mitsuba_scene_dict(
    scene,
    width: int | None = None,
    height: int | None = None,
    max_depth: int | None = None,
    absorption: str = "ignore",
    notes: list | None = None,
) -> dict:
    """The Mitsuba 3 scene dictionary of the raylume Scene `scene` (raylume.load_scene's result).
    width, height and max_depth default to the scene's [render] values. absorption: "ignore" (the
    `path` integrator, glass without absorption) or "medium" (`volpath` and an absorbing medium
    inside each dielectric with absorption). Approximations made are appended to `notes`."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    notes = notes if notes is not None else []
    if absorption not in ("ignore", "medium"):
        raise ValueError(f"absorption must be 'ignore' or 'medium', got {absorption!r}")
    settings = scene.render
    width = width or settings.width
    height = height or settings.height
    depth = settings.depth if max_depth is None else max_depth
    if scene.lights:
        raise SystemExit("mitsuba_scene: [[lights]] are not translated (only the environment and no emission)")
    if scene.animation is not None:
        notes.append("the animation is ignored (frame 0's scene as written)")

    cam = scene.camera
    p, f, _, up = camera_frame(cam)
    sensor = {
        "type": "thinlens" if cam.aperture > 0 else "perspective",
        "fov": float(cam.fov),
        "fov_axis": "y",
        "near_clip": 1e-3,
        "far_clip": 10 * PLANE_HALF_SIZE,
        "to_world": T().look_at(origin=to_mitsuba(p), target=to_mitsuba(p + f), up=to_mitsuba(up)),
        "sampler": {"type": "independent", "sample_count": max(1, int(settings.spp))},
        "film": {
            "type": "hdrfilm",
            "width": int(width),
            "height": int(height),
            "pixel_format": "rgb",
            "component_format": "float32",
            "rfilter": {
                "box": {"type": "box"},
                "gaussian": {"type": "gaussian", "stddev": 0.5},
                "mitchell": {"type": "mitchell", "B": 1 / 3, "C": 1 / 3},
            }[settings.filter],
        },
    }
    if cam.aperture > 0:
        sensor["aperture_radius"] = float(cam.aperture) / 2
        sensor["focus_distance"] = float(cam.focus)
    out = {"type": "scene", "sensor": sensor}

    use_medium = absorption == "medium" and any(
        getattr(scene.material_of(o), "type", "") == "dielectric" and any(scene.material_of(o).absorption)
        for o in scene.objects
    )
    out["integrator"] = {"type": "volpath" if use_medium else "path", "max_depth": int(depth), "rr_depth": 5}

    # ------------------------------------------------------------------ environment
    env = scene.environment
    if env is None:
        if any(settings.background):
            notes.append("render.background is not translated (Mitsuba has no background without an emitter)")
    elif env.color is not None:
        out["environment"] = {
            "type": "constant",
            "radiance": {"type": "rgb", "value": [c * env.intensity for c in env.color]},
        }
    else:
        path = Path(env.file)
        if not path.is_absolute():
            path = Path(scene.base_dir) / path
        to_world = T(_matrix4(MIRROR @ rotation(env.rotate) @ MIRROR))
        out["environment"] = {"type": "envmap", "scale": float(env.intensity), "to_world": to_world}
        # the texels raylume renders with (Mitsuba's own .hdr reader decodes RGBE without the +0.5)
        from raylume.compile.environment import load_environment_image

        texels = pole_to_pole_rows(load_environment_image(path))
        out["environment"]["bitmap"] = mi.Bitmap(np.ascontiguousarray(texels, np.float32))

    # ------------------------------------------------------------------ materials
    def colour(mat, where: str, plane=None):
        """A Mitsuba spectrum/texture for the material's colour (or its texture)."""
        tex = mat.texture
        if tex is None:
            return {"type": "rgb", "value": [float(c) for c in mat.color]}
        if tex.type != "checker":
            raise SystemExit(f"mitsuba_scene: {where}: {tex.type} textures are not translated")
        s = float(tex.scale)
        a, b = ([float(c) for c in col] for col in tex.colors)
        if plane is None or plane["axis"] is None:
            notes.append(f"{where}: raylume's 3D world-space checker approximated by a uv checkerboard")
            return {"type": "checkerboard", "color0": _rgb(a), "color1": _rgb(b)}
        # The rectangle's uv: u = (x_i - c_i) / (2 L) + 1/2 along the plane's axis i (the same for v,
        # j); to_uv scales by L / s, so 2 u' = (x_i - c_i) / s + L / s = x_i / s + an even number
        # (c_i a multiple of 2 s, L an even multiple of s): Mitsuba's cell index floor(2 u') has
        # the parity of raylume's floor(x_i / s). The plane's constant coordinate adds its own.
        half = plane["half"]
        if abs(half / s - round(half / s)) > 1e-9 or round(half / s) % 2:
            notes.append(f"{where}: the plane's half-side is not an even multiple of the checker cell")
        odd = math.floor(plane["offset"] / s + 1e-9) % 2 == 1
        c0, c1 = (b, a) if odd else (a, b)
        return {
            "type": "checkerboard",
            "color0": _rgb(c0),
            "color1": _rgb(c1),
            "to_uv": T().scale([half / s, half / s, 1.0]),
        }

    def bsdf(mat, where: str, plane=None) -> dict:
        kind = getattr(mat, "type", "phong")
        rough = float(getattr(mat, "roughness", 0.0))
        if any(mat.emission):
            raise SystemExit(f"mitsuba_scene: {where}: emissive materials are not translated")
        if kind == "diffuse":
            inner = {"type": "diffuse", "reflectance": colour(mat, where, plane)}
        elif kind == "conductor":
            inner = {"type": "roughconductor" if rough > 0 else "conductor"}
            if mat.eta is not None:
                inner["eta"] = {"type": "rgb", "value": list(mat.eta)}
                inner["k"] = {"type": "rgb", "value": list(mat.k)}
            else:
                inner["material"] = "none"
            if mat.texture is not None or any(c != 1.0 for c in mat.color):
                inner["specular_reflectance"] = colour(mat, where, plane)
        elif kind == "dielectric":
            d = {"type": "roughdielectric" if rough > 0 else "dielectric", "int_ior": float(mat.ior), "ext_ior": 1.0}
            if mat.texture is not None or any(c != 1.0 for c in mat.color):
                d["specular_transmittance"] = colour(mat, where, plane)
            if rough > 0:
                d.update(distribution="ggx", alpha=rough)
            return d  # one-sided, as raylume's: the normal faces out
        elif kind == "plastic":
            inner = {
                "type": "roughplastic" if rough > 0 else "plastic",
                "diffuse_reflectance": colour(mat, where, plane),
                "int_ior": min(max(float(mat.ior), 1.0), PLASTIC_ETA_MAX),
                "ext_ior": 1.0,
                "nonlinear": False,
            }
        else:
            raise SystemExit(f"mitsuba_scene: {where}: {kind} materials are not translated")
        if rough > 0:
            inner.update(distribution="ggx", alpha=rough)  # Mitsuba's default is beckmann
        return {"type": "twosided", "bsdf": inner}

    def medium_of(mat):
        if use_medium and getattr(mat, "type", "") == "dielectric" and any(mat.absorption):
            return {
                "type": "homogeneous",
                "sigma_t": {"type": "rgb", "value": [float(a) for a in mat.absorption]},
                "albedo": 0.0,
            }
        return None

    absorbing = sorted(
        {
            o.material if isinstance(o.material, str) else f"objects[{k}]"
            for k, o in enumerate(scene.objects)
            if getattr(scene.material_of(o), "type", "") == "dielectric" and any(scene.material_of(o).absorption)
        }
    )
    if absorbing and not use_medium:
        notes.append(f"absorption inside {', '.join(absorbing)} ignored (Mitsuba's path integrator has no media)")

    # ------------------------------------------------------------------ objects
    for k, obj in enumerate(scene.objects):
        mat = scene.material_of(obj)
        where = f"objects[{k}] ({obj.type}, material {obj.material if isinstance(obj.material, str) else 'inline'})"
        if obj.type == "sphere":
            shape = {"type": "sphere", "center": to_mitsuba(obj.center), "radius": float(obj.radius)}
            shape["bsdf"] = bsdf(mat, where)
        elif obj.type == "plane":
            n = np.array(obj.normal, float)
            n /= np.linalg.norm(n)
            axis = int(np.argmax(np.abs(n)))
            aligned = abs(abs(n[axis]) - 1.0) < 1e-12
            if aligned:
                i, j = [a for a in range(3) if a != axis]
                e_i, e_j = np.eye(3)[i], np.eye(3)[j]
            else:
                helper = np.eye(3)[int(np.argmin(np.abs(n)))]
                e_i = np.cross(helper, n)
                e_i /= np.linalg.norm(e_i)
                e_j = np.cross(n, e_i)
            # centred on the camera's foot on the plane, rounded to whole pairs of checker cells
            q = np.array(obj.point, float)
            foot = p - np.dot(p - q, n) * n
            cell = float(mat.texture.scale) if getattr(mat, "texture", None) is not None else 1.0
            centre = foot.copy()
            if aligned:
                for a in (i, j):
                    centre[a] = 2 * cell * round(foot[a] / (2 * cell))
                centre[axis] = q[axis]
            half = 2 * cell * math.ceil(PLANE_HALF_SIZE / (2 * cell))
            # columns: local x -> L e_i, y -> L e_j, z -> +-n; the sign keeps det(M A) > 0 in
            # Mitsuba's frame (a mirroring to_world would flip the rectangle's normal)
            sign = -1.0 if np.linalg.det(np.column_stack([e_i, e_j, n])) > 0 else 1.0
            a3 = MIRROR @ np.column_stack([half * e_i, half * e_j, sign * n])
            plane = {"axis": axis if aligned else None, "half": half, "offset": float(q[axis])}
            shape = {"type": "rectangle", "to_world": T(_matrix4(a3, to_mitsuba(centre)))}
            shape["bsdf"] = bsdf(mat, where, plane)
            if getattr(mat, "type", "") == "dielectric":
                notes.append(f"{where}: a dielectric plane's outside may face the other way in Mitsuba")
        else:
            raise SystemExit(f"mitsuba_scene: {where}: {obj.type} objects are not translated")
        medium = medium_of(mat)
        if medium is not None:
            shape["interior"] = medium
        out[f"object_{k}"] = shape
    return out


# --------------------------------------------------------------------------- compare


def srgb8(rgb: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    x = np.clip(rgb * 2.0**exposure, 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (x * 255 + 0.5).astype(np.uint8)


def blocks(img: np.ndarray, b: int) -> np.ndarray:
    h, w = img.shape[0] // b * b, img.shape[1] // b * b
    return img[:h, :w].reshape(h // b, b, w // b, b, 3).mean(axis=(1, 3))


def compare(args) -> None:
    import drjit as dr
    import mitsuba as mi

    import raylume

    mi.set_variant(args.variant)
    dr.set_thread_count(args.threads)
    scene = load(args.scene)
    W, H, spp = args.width, args.height, args.spp
    clear = scene.replace(
        materials={
            name: {"absorption": [0.0, 0.0, 0.0]}
            for name, m in scene.materials.items()
            if getattr(m, "type", "") == "dielectric" and any(m.absorption)
        }
    )
    rows = []
    for label, ray_scene, absorption in (
        ("no absorption on either side (path)", clear, "ignore"),
        ("absorption on both sides (Mitsuba volpath + medium)", scene, "medium"),
        ("as benchmarked: raylume absorbs, Mitsuba's path ignores it", scene, "ignore"),
    ):
        notes: list = []
        d = mitsuba_scene_dict(scene, W, H, absorption=absorption, notes=notes)
        t = time.perf_counter()
        ours = np.zeros((H, W, 3))
        theirs = np.zeros((H, W, 3))
        for s in range(args.seeds):
            img = raylume.render(ray_scene, width=W, height=H, spp=spp, seed=s, mode="path", aovs=False)
            ours += np.asarray(img.rgb, np.float64) / args.seeds
        t_ours = time.perf_counter() - t
        t = time.perf_counter()
        ms = mi.load_dict(d)
        for s in range(args.seeds):
            theirs += np.array(mi.render(ms, seed=s, spp=spp), np.float64)[:, :, :3] / args.seeds
        t_theirs = time.perf_counter() - t
        print(f"\n## {label}  (raylume {t_ours:.1f} s, Mitsuba {args.variant} {t_theirs:.1f} s)")
        for n in notes:
            print(f"  note: {n}")
        mo, mt = ours.mean(axis=(0, 1)), theirs.mean(axis=(0, 1))
        print(f"  mean rgb raylume {np.round(mo, 4)}  Mitsuba {np.round(mt, 4)}; ratio {np.round(mo / mt, 4)}")
        bo, bt = blocks(ours, args.block), blocks(theirs, args.block)
        rel = (bo - bt).mean(axis=2) / np.maximum(bt.mean(axis=2), 1e-3)
        print(
            f"  {args.block} x {args.block}-pixel block means, (raylume - Mitsuba) / Mitsuba, grey; "
            f"median |.| {np.median(np.abs(rel)):.3f}, max |.| {np.abs(rel).max():.3f}:"
        )
        for row in rel:
            print("   " + " ".join(f"{v:+.2f}" for v in row))
        exp = settings_exposure(scene)
        diff = np.abs(ours - theirs) * 4
        rows.append(np.concatenate([srgb8(ours, exp), srgb8(theirs, exp), srgb8(diff, exp)], axis=1))
    sheet = np.concatenate(rows, axis=0)
    from PIL import Image

    Image.fromarray(sheet).save(args.out)
    print(
        f"\nwrote {args.out}: rows as above; columns raylume | Mitsuba | |difference| x 4 "
        f"(sRGB, exposure {settings_exposure(scene):+g})"
    )


def settings_exposure(scene) -> float:
    return float(scene.render.exposure)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("compare", help="render with raylume and Mitsuba and compare")
    p.add_argument("scene", nargs="?", default=str(MATERIALS))
    p.add_argument("--width", type=int, default=160)
    p.add_argument("--height", type=int, default=80)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--seeds", type=int, default=1, help="renders averaged per side")
    p.add_argument("--block", type=int, default=16, help="block size of the downscaled difference")
    p.add_argument("--variant", default="scalar_rgb")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--out", default="/tmp/materials_compare.png")
    p = sub.add_parser("dict", help="print the Mitsuba dictionary and the notes")
    p.add_argument("scene", nargs="?", default=str(MATERIALS))
    args = parser.parse_args(argv)
    if args.command == "compare":
        compare(args)
    else:
        import mitsuba as mi

        mi.set_variant("scalar_rgb")
        notes: list = []
        d = mitsuba_scene_dict(load(args.scene), notes=notes)
        for key, value in d.items():
            if key == "environment" and "bitmap" in value:
                value = {**value, "bitmap": f"<{value['bitmap'].width()} x {value['bitmap'].height()} texels>"}
            print(f"{key}: {value}")
        for n in notes:
            print(f"note: {n}")


if __name__ == "__main__":
    from common import run_main  # (here: tests import this module for its scene conversion)

    run_main(main)
