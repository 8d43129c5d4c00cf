"""Render every picture that README.md and the documentation show, each from the exact command
the gallery page prints beside it (`make gallery`).

    python tools/gallery.py [NAME ...] [--list]

`tests/test_gallery.py` renders each picture again at a small size from the same command and
compares it with the committed picture's downscale, so a picture that no longer matches what its
command renders fails the suite. The pictures made by benchmarks (plots, the viewer's screenshot)
are not here: their commands are in the performance page and they are not renders of a scene.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Picture:
    """One picture of the docs: `raylume render ARGS` writes it, from the repository root."""

    name: str
    title: str
    args: tuple[str, ...]  # after `raylume render`, -o docs/images/... included
    encoding: str  # the scene's 8-bit encoding, to average the committed picture in linear light
    # The small render that checks it: the committed picture is box-downscaled by `factor`, and the
    # command is rendered at that size with `check_spp` samples per pixel (stratified in the pixel,
    # so that they average over the same area the downscale does) and `check_args` appended.
    factor: int
    check_spp: int
    # Mean absolute difference allowed, in 8-bit levels, between blocks of BLOCK x BLOCK pixels of the small
    # render and of the downscale; `tolerance_note` has the difference measured on a fresh picture.
    tolerance: float
    tolerance_note: str
    check_args: tuple[str, ...] = ()
    setup: tuple[str, ...] = ()  # a command run first (a generator of the scene's files)
    note: str = ""
    frame: int | None = None  # an animation: the frame of the committed GIF that is compared
    # Deterministic pictures (trace mode, no denoiser) are also rendered at full size in a window of
    # 1/crop_part of each side at the centre (--crop renders that window bit for bit as the full render
    # does), and compared pixel by pixel: at most CROP_PIXELS_OFF of the pixels may be off by more than
    # 2 levels. None: no such check.
    crop_part: int | None = 2
    # A denoised picture's window is denoised by itself, so its pixels near the window's edges differ from the
    # full picture's: those within crop_margin pixels of an edge are left out, and DENOISED_PIXELS_OFF applies.
    crop_margin: int = 0

    @property
    def path(self) -> Path:
        return REPO / self.output

    @property
    def output(self) -> str:
        return self.args[self.args.index("-o") + 1]

    @property
    def command(self) -> str:
        return "raylume render " + shlex.join(self.args)


# Tolerances: a fresh small render differs from a fresh picture's downscale by the sampling of edges and
# textures (1 spp at full size samples each small pixel on a regular grid of factor x factor points, the small
# render at check_spp stratified random points, and filters textures over its own, wider pixel footprint) and,
# in path mode, by Monte Carlo noise and the denoiser working on a tiny image. Both are noise, so they are
# averaged down by comparing blocks of BLOCK x BLOCK small pixels, where a stale picture's difference (a
# changed colour, shading or framing over an area) stays. Each tolerance is about twice the fresh difference
# measured by `python tools/gallery.py --measure` (noted beside it): the renders are deterministic (fixed
# seeds), so the margin is for other CPUs' rounding only. Finer staleness (the checker moire of issue 47's
# meshes.png, 0.5 levels in blocks) is the full-size crop check's (CROP_PIXELS_OFF).
BLOCK = 4

PICTURES: tuple[Picture, ...] = (
    Picture(
        name="seed",
        title="The seed scene, built in: the lecture's four spheres",
        args=("-o", "docs/images/seed.png"),
        encoding="clamp",
        factor=8,
        check_spp=16,
        tolerance=0.5,
        tolerance_note="fresh 0.06",
    ),
    Picture(
        name="seed_cast",
        title="Ray casting: the seed scene, one ray per pixel, each hit's material colour",
        args=("--mode", "cast", "--width", "300", "--height", "300", "-o", "docs/images/seed_cast.png"),
        encoding="clamp",
        factor=4,
        check_spp=16,
        tolerance=0.5,
        tolerance_note="fresh 0.12",
    ),
    Picture(
        name="glass",
        title="Glass: refraction, Fresnel, total internal reflection, absorption",
        args=("examples/glass.toml", "-o", "docs/images/glass.png"),
        encoding="srgb",
        factor=10,
        check_spp=16,
        tolerance=1.0,
        tolerance_note="fresh 0.46",
    ),
    Picture(
        name="mirrors",
        title="A hall of mirrors",
        args=("examples/mirrors.toml", "-o", "docs/images/mirrors.png"),
        encoding="srgb",
        factor=8,
        check_spp=16,
        tolerance=0.8,
        tolerance_note="fresh 0.31",
    ),
    Picture(
        name="meshes",
        title="Meshes: a glass teapot, Spot the cow, a mirror ball",
        args=("examples/meshes.toml", "-o", "docs/images/meshes.png"),
        encoding="srgb",
        factor=8,
        check_spp=16,
        tolerance=1.0,
        tolerance_note="fresh 0.52",
    ),
    Picture(
        name="quality",
        title="Image quality: area lights, textures, depth of field",
        args=("examples/quality.toml", "--spp", "64", "-o", "docs/images/quality.png"),
        encoding="srgb",
        factor=8,
        check_spp=16,
        tolerance=2.0,
        tolerance_note="fresh 0.92: 16 against 64 samples of soft shadows and depth of field",
        crop_part=8,
        note="The file asks for 16 samples per pixel; the picture has 64.",
    ),
    Picture(
        name="surface_maps",
        title="Surface maps: a normal-mapped floor, a bump-mapped sphere, a lattice cut by an alpha map",
        args=("examples/surface_maps.toml", "--spp", "16", "-o", "docs/images/surface_maps.png"),
        encoding="srgb",
        factor=8,
        check_spp=64,
        tolerance=5.0,
        tolerance_note="fresh 2.61: the maps' bevels, dimples and lattice edges, unfiltered, at 80 x 45",
        note="The file asks for 4 samples per pixel; the picture has 16.",
    ),
    Picture(
        name="cornell",
        title="Path tracing: the Cornell box, 256 spp, denoised",
        args=(
            "examples/cornell.toml",
            "--width",
            "400",
            "--height",
            "400",
            "--spp",
            "256",
            "--denoise",
            "-o",
            "docs/images/cornell.png",
        ),
        encoding="srgb",
        factor=8,
        check_spp=64,
        tolerance=2.5,
        tolerance_note="fresh 1.09: path-tracing noise of 64 spp, denoised, at 50 x 50",
        crop_part=4,
        crop_margin=16,
        note="75 s on 2 cores.",
    ),
    Picture(
        name="materials",
        title="Path-traced materials under an HDR sky, 64 spp, denoised",
        args=("examples/materials.toml", "--denoise", "-o", "docs/images/materials.png"),
        encoding="srgb",
        factor=8,
        check_spp=64,
        tolerance=4.0,
        tolerance_note="fresh 2.09: path-tracing noise of 64 spp under an HDR sky, denoised, at 80 x 40",
        crop_part=4,
        crop_margin=16,
        note="9 s on 2 cores.",
    ),
    Picture(
        name="fog",
        title="Participating media: light shafts of a spot light in fog",
        args=("examples/fog.toml", "--denoise", "-o", "docs/images/fog.png"),
        encoding="srgb",
        factor=6,
        check_spp=32,
        tolerance=9.0,
        tolerance_note="fresh 4.53: the light the fog scatters, 32 spp, denoised at 80 x 45",
        crop_part=4,
        crop_margin=16,
    ),
    Picture(
        name="smoke",
        title="Participating media: a plume of smoke from a density grid",
        args=("examples/smoke.toml", "--denoise", "-o", "docs/images/smoke.png"),
        encoding="srgb",
        factor=8,
        check_spp=32,
        tolerance=2.0,
        tolerance_note="fresh 0.96: 32 spp, denoised at 45 x 50",
        # The denoiser on a window of the smoke differs from the whole picture's by up to 20 levels (it measures
        # its exposure over what it is given; a third of the pixels moved by more than 2 levels): the downscale alone.
        crop_part=None,
        setup=("python", "examples/smoke/make_smoke.py"),
        note="Generate the density grid first: `python examples/smoke/make_smoke.py`.",
    ),
    Picture(
        name="translucent",
        title="Participating media: Spot as milky jade beside a sphere of milk (subsurface scattering)",
        args=("examples/translucent.toml", "--denoise", "-o", "docs/images/translucent.png"),
        encoding="srgb",
        factor=6,
        check_spp=32,
        tolerance=3.0,
        tolerance_note="fresh 1.57: subsurface scattering at 32 spp, denoised at 80 x 50",
        crop_part=4,
        crop_margin=16,
    ),
    Picture(
        name="gltf_room",
        title="A glTF scene: its own camera, lights, PBR materials and instances",
        args=(
            "examples/gltf/room.glb",
            "--width",
            "480",
            "--spp",
            "64",
            "--denoise",
            "-o",
            "docs/images/gltf_room.png",
        ),
        encoding="srgb",
        factor=8,
        check_spp=64,
        tolerance=4.0,
        tolerance_note="fresh 1.83: path-tracing noise of 64 spp, denoised, at 60 x 45",
        crop_part=4,
        crop_margin=16,
        note="`examples/gltf/room.glb` is written by `python examples/gltf/make_room.py`. 71 s on 2 busy cores.",
    ),
    Picture(
        name="forest",
        title="10 000 instanced trees: a billion triangles",
        args=("examples/forest.toml", "--width", "640", "--height", "480", "-o", "docs/images/forest.png"),
        encoding="srgb",
        factor=8,
        check_spp=16,
        tolerance=1.0,
        tolerance_note="fresh 0.41: a billion needles' sub-pixel detail",
        setup=("python", "examples/forest/make_forest.py"),
        note="Generate the meshes and placements first: `python examples/forest/make_forest.py` (a few seconds).",
    ),
    Picture(
        name="flight",
        title="A camera flight around the seed scene (72 frames)",
        args=(
            "examples/flight.toml",
            "--width",
            "160",
            "--height",
            "120",
            "--spp",
            "4",
            "-o",
            "docs/images/flight.gif",
        ),
        encoding="clamp",
        factor=4,
        check_spp=16,
        tolerance=2.0,
        tolerance_note="fresh 0.92: the GIF's 256-colour palette",
        # A GIF's frames are quantised to 256 colours: a quarter of the pixels of a fresh frame are more than 2
        # levels off; the downscale averages that out.
        crop_part=None,
        check_args=("--frame", "30"),
        frame=30,
    ),
)


def by_name(name: str) -> Picture:
    for picture in PICTURES:
        if picture.name == name:
            return picture
    raise KeyError(f"no gallery picture named {name!r}; pictures: {', '.join(p.name for p in PICTURES)}")


def raylume_argv() -> list[str]:
    """`raylume` as this interpreter runs it, with the repository's src first (no install needed)."""
    return [sys.executable, "-c", "import sys; sys.path.insert(0, 'src'); from raylume.cli import main; main()"]


def run_setup(picture: Picture) -> None:
    """Make the files the scene needs (a generator script; deterministic, so a second run changes nothing)."""
    if picture.setup:
        subprocess.run([sys.executable, *picture.setup[1:]], cwd=REPO, check=True, stdout=subprocess.DEVNULL)


def render(picture: Picture) -> float:
    """Render one picture into docs/images as its command says; returns the seconds it took."""
    start = time.perf_counter()
    run_setup(picture)
    subprocess.run([*raylume_argv(), "render", *picture.args], cwd=REPO, check=True)
    return time.perf_counter() - start


def _to_linear(levels: np.ndarray, encoding: str) -> np.ndarray:
    x = levels.astype(np.float64) / 255.0
    if encoding == "srgb":
        return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)
    return x


def _to_levels(linear: np.ndarray, encoding: str) -> np.ndarray:
    x = np.clip(linear, 0.0, 1.0)
    if encoding == "srgb":
        x = np.where(x <= 0.0031308, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055)
    return x * 255.0


def committed_downscale(picture: Picture) -> np.ndarray:
    """The committed picture, box-averaged over `factor` x `factor` pixels in linear light, as
    8-bit levels (float). An animation's GIF gives its frame `picture.frame`."""
    with Image.open(picture.path) as image:
        if picture.frame is not None:
            image.seek(picture.frame)
        rgb = np.asarray(image.convert("RGB"))
    k = picture.factor
    h, w = rgb.shape[0] // k * k, rgb.shape[1] // k * k
    linear = _to_linear(rgb[:h, :w], picture.encoding)
    small = linear.reshape(h // k, k, w // k, k, 3).mean(axis=(1, 3))
    return _to_levels(small, picture.encoding)


def small_render_args(picture: Picture, out: Path) -> list[str]:
    """The picture's command at the checked size: later flags override the command's own."""
    with Image.open(picture.path) as image:
        width, height = image.size
    k = picture.factor
    if width % k or height % k:  # a cropped downscale would not show the same field of view
        raise ValueError(f"{picture.name}: {width} x {height} is not divisible by the factor {k}")
    return [
        *picture.args,
        *picture.check_args,
        *("--width", str(width // k), "--height", str(height // k), "--spp", str(picture.check_spp)),
        *("-o", str(out), "--quiet"),
    ]


# Rounding may differ between CPUs (fused multiply-adds, vector widths): a few pixels a level or two off.
# The stale pictures of issue 47 had 5.2% (glass), 8.6% (mirrors) and 23% (meshes) of their pixels off.
CROP_PIXELS_OFF = 0.005
# A denoised window (its margins left out) differs a little everywhere: Open Image Denoise scales its input by
# an exposure measured over the whole image it is given. So its pixels count as off beyond 8 levels, and 2% may
# be: fresh, 0.0% (materials) and 0.1% (gltf_room) were; 11.5% of materials' were before it was rendered again
# (issue 47's stale picture; 45% beyond 2 levels).
DENOISED_LEVELS = 8
DENOISED_PIXELS_OFF = 0.02


def pixels_off_allowed(picture: Picture) -> float:
    return DENOISED_PIXELS_OFF if picture.crop_margin else CROP_PIXELS_OFF


def crop_window(picture: Picture) -> tuple[int, int, int, int]:
    with Image.open(picture.path) as image:
        width, height = image.size
    w, h = width // picture.crop_part, height // picture.crop_part
    x0, y0 = (width - w) // 2, (height - h) // 2
    return x0, x0 + w, y0, y0 + h


def crop_render_args(picture: Picture, out: Path) -> list[str]:
    x0, x1, y0, y1 = crop_window(picture)
    return [*picture.args, *picture.check_args, "--crop", f"{x0}:{x1},{y0}:{y1}", "-o", str(out), "--quiet"]


def crop_pixels_off(picture: Picture, crop_png: Path) -> float:
    """The share of the window's pixels that differ from the committed picture's by more than 2 levels (a denoised
    picture's: more than DENOISED_LEVELS, its margins left out)."""
    x0, x1, y0, y1 = crop_window(picture)
    with Image.open(picture.path) as image:
        if picture.frame is not None:
            image.seek(picture.frame)
        committed = np.asarray(image.convert("RGB")).astype(np.int16)[y0:y1, x0:x1]
    with Image.open(crop_png) as image:
        rendered = np.asarray(image.convert("RGB")).astype(np.int16)
    off = np.abs(rendered - committed).max(axis=2) > (DENOISED_LEVELS if picture.crop_margin else 2)
    m = picture.crop_margin
    return float((off[m : off.shape[0] - m, m : off.shape[1] - m] if m else off).mean())


def _blocks(levels: np.ndarray) -> np.ndarray:
    h, w = levels.shape[0] // BLOCK * BLOCK, levels.shape[1] // BLOCK * BLOCK
    return levels[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, 3).mean(axis=(1, 3))


def mean_difference(picture: Picture, small_png: Path) -> float:
    """Mean absolute difference, in 8-bit levels, between blocks of BLOCK x BLOCK pixels of a small render and
    of the committed picture's downscale."""
    with Image.open(small_png) as image:
        rendered = np.asarray(image.convert("RGB")).astype(np.float64)
    expected = committed_downscale(picture)
    return float(np.abs(_blocks(rendered) - _blocks(expected)).mean())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="pictures to render (default: all)")
    parser.add_argument(
        "--list", action="store_true", help="print each picture's command (after its setup, if any) and exit"
    )
    parser.add_argument(
        "--measure", action="store_true", help="render each at the test's small size and print its difference"
    )
    args = parser.parse_args(argv)
    chosen = [by_name(n) for n in args.names] if args.names else list(PICTURES)
    width = max(len(picture.name) for picture in chosen)
    for picture in chosen:
        if args.list:  # one line each, to copy as it is: the setup (a generator of the scene's files) first
            setup = f"{shlex.join(picture.setup)} && " if picture.setup else ""
            print(f"{picture.name:<{width}}  {setup}{picture.command}")
            continue
        if args.measure:
            run_setup(picture)
            out = REPO / "out" / f"gallery_small_{picture.name}.png"
            out.parent.mkdir(exist_ok=True)
            start = time.perf_counter()
            subprocess.run([*raylume_argv(), "render", *small_render_args(picture, out)], cwd=REPO, check=True)
            seconds = time.perf_counter() - start
            difference = mean_difference(picture, out)
            line = f"{picture.name:<10} {difference:5.2f} levels (tolerance {picture.tolerance}) {seconds:5.1f} s"
            if picture.crop_part is not None:
                start = time.perf_counter()
                crop = out.with_name(f"gallery_crop_{picture.name}.png")
                subprocess.run([*raylume_argv(), "render", *crop_render_args(picture, crop)], cwd=REPO, check=True)
                off = crop_pixels_off(picture, crop)
                seconds = time.perf_counter() - start
                line += f"; crop: {off:.2%} of pixels off (at most {pixels_off_allowed(picture):.1%}) {seconds:5.1f} s"
            print(line)
            continue
        seconds = render(picture)
        size = picture.path.stat().st_size // 1024
        print(f"{picture.name:<10} {seconds:6.1f} s  {size} KiB  {picture.command}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
