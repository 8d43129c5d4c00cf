"""The documentation's pictures cannot go stale: each is rendered again from the exact command that the
gallery shows for it (tools/gallery.py), at a small size, and compared with the committed picture's
downscale; each deterministic (trace-mode) picture is also rendered at full size in a window (--crop) and
compared pixel by pixel. The tolerances and how they were measured are in tools/gallery.py."""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

import pytest
from PIL import Image
from typer.testing import CliRunner

from raylume.cli import app

REPO = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("gallery", REPO / "tools" / "gallery.py")
gallery = importlib.util.module_from_spec(_spec)
sys.modules["gallery"] = gallery
_spec.loader.exec_module(gallery)


def _render(args: list[str]) -> None:
    result = CliRunner().invoke(app, ["render", *args])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("picture", gallery.PICTURES, ids=[p.name for p in gallery.PICTURES])
def test_picture_matches_its_command(picture, tmp_path, monkeypatch):
    monkeypatch.chdir(REPO)  # the commands name files from the repository's root, as the gallery page says
    gallery.run_setup(picture)
    small = tmp_path / "small.png"
    _render(gallery.small_render_args(picture, small))
    difference = gallery.mean_difference(picture, small)
    assert difference <= picture.tolerance, (
        f"{picture.path.name} differs from what `{picture.command}` renders now by {difference:.2f} levels "
        f"(tolerance {picture.tolerance}, {picture.tolerance_note}): run `python tools/gallery.py {picture.name}`"
    )
    if picture.crop_part is not None:
        crop = tmp_path / "crop.png"
        _render(gallery.crop_render_args(picture, crop))
        off = gallery.crop_pixels_off(picture, crop)
        assert off <= gallery.pixels_off_allowed(picture), (
            f"{picture.path.name}: {off:.1%} of the pixels of a full-size window differ from "
            f"what `{picture.command}` renders now: run `python tools/gallery.py {picture.name}`"
        )


def test_pictures_are_small_and_every_docs_picture_is_in_the_gallery():
    rendered = {p.path.name for p in gallery.PICTURES}
    # benchmarks' output (the head lamps are bench_bdpt.py's equal-time renders, not a command's)
    plots = {"bvh_scaling.png", "hits_scaling.png", "instances.png", "path_rmse.png", "scaling.png", "view.png"}
    plots |= {"bdpt_rmse.png", "adaptive_spp.png"}
    plots |= {"headlamp_bdpt.png", "headlamp_path.png", "headlamp_compare.png"}
    for image in (REPO / "docs" / "images").iterdir():
        assert image.stat().st_size <= 450_000, f"{image.name}: keep the pictures small"
        assert image.name in rendered | plots, f"{image.name}: not in tools/gallery.py"
    for picture in gallery.PICTURES:
        with Image.open(picture.path) as image:
            assert image.size[0] % picture.factor == 0 and image.size[1] % picture.factor == 0, picture.name


def test_a_stale_picture_fails(tmp_path, monkeypatch):
    """The checks catch the staleness issue 47 found: the meshes picture before it was rendered again."""
    monkeypatch.chdir(REPO)
    stale = tmp_path / "meshes_stale.png"
    fresh = gallery.by_name("meshes")
    # the committed picture with its checker floor's moire back: every other column of the floor shifted
    with Image.open(fresh.path) as image:
        rgb = image.convert("RGB")
    pixels = rgb.load()
    for y in range(rgb.height // 2, rgb.height):
        for x in range(0, rgb.width, 2):
            pixels[x, y] = tuple(min(255, c + 12) for c in pixels[x, y])
    rgb.save(stale)
    picture = replace(fresh, args=tuple(str(stale) if a == fresh.output else a for a in fresh.args))
    crop = tmp_path / "crop.png"
    _render(gallery.crop_render_args(picture, crop))
    assert gallery.crop_pixels_off(picture, crop) > gallery.CROP_PIXELS_OFF
