"""The Python API's front door. `render`, `Session` take a scene as the command line's SCENE
does (scene/open.py): a built-in name, a scene file or a mesh file, beside a Scene; each is
checked against the other way of getting the same picture (the Scene built by hand, or the
command line's own output). And `import raylume` is cheap: its names load on first use."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from test_cli import raylume as run_cli

import raylume

EXAMPLES = Path(__file__).parent.parent / "examples"
SMALL = dict(width=24, height=16, aovs=False)


def test_a_built_in_name_renders_that_scene():
    by_name = raylume.render("seed", **SMALL)
    by_scene = raylume.render(raylume.builtin_scene("seed"), **SMALL)
    assert np.array_equal(by_name.rgb, by_scene.rgb)
    assert raylume.Session("seed").source == "built-in scene 'seed'"
    assert np.array_equal(raylume.render(None, **SMALL).rgb, by_scene.rgb)  # None: the default scene


def test_a_scene_file_path_renders_that_file():
    path = EXAMPLES / "glass.toml"
    by_path = raylume.render(path, **SMALL)
    by_scene = raylume.render(raylume.load_scene(path), **SMALL)
    assert np.array_equal(by_path.rgb, by_scene.rgb)
    session = raylume.Session(str(path))
    assert session.source == str(path)
    assert np.array_equal(session.render(**SMALL).rgb, by_scene.rgb)


def test_a_mesh_file_renders_as_the_command_line_frames_it(tmp_path):
    path = tmp_path / "ball.ply"
    trimesh.creation.icosphere(subdivisions=2).export(path)
    image = raylume.render(path, width=24, height=16)
    result = run_cli("render", path, "--width", 24, "--height", 16, "-o", "cli.npy", "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert np.array_equal(image.rgb, np.load(tmp_path / "cli.npy"))
    assert (image.aovs["object"] == 0).any()  # the mesh is in the frame


def test_what_is_not_a_scene_is_refused_by_name(tmp_path):
    with pytest.raises(TypeError, match="raylume.Scene.*got int"):
        raylume.render(3)
    with pytest.raises(raylume.SceneError, match="nosuch.toml"):
        raylume.Session(tmp_path / "nosuch.toml")
    with pytest.raises(raylume.SceneError, match="not a scene file.*built-ins: .*seed"):
        raylume.render("no-such-built-in")


def test_importing_raylume_loads_no_kernels():
    """The package imports its public names on first use: `import raylume` and the command
    line's --help do not load Numba (1.5 s), while every public name still resolves."""
    code = (
        "import sys, raylume, raylume.cli; loaded = 'numba' in sys.modules; "
        "from raylume.render import check_memory; "  # the module render.py loaded: raylume.render stays the function
        "names = [getattr(raylume, n) for n in raylume.__all__]; "
        "print(loaded, 'numba' in sys.modules, callable(raylume.render))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "True", "True"]


@pytest.mark.parametrize(
    "call, error, words",
    [
        (lambda: raylume.render("seed", crop=(0, 10), **SMALL), raylume.errors.RaylumeError, "crop must be four whole"),
        (lambda: raylume.render("seed", crop="0:10,0:10", **SMALL), raylume.errors.RaylumeError, "crop must be four"),
        (lambda: raylume.render("seed", crop=(0, 10, 0, 12.5), **SMALL), raylume.errors.RaylumeError, "crop must be"),
        (lambda: raylume.render("seed", threads=2.0, **SMALL), ValueError, "threads must be a whole number"),
        (lambda: raylume.Session("seed").render(camera="top", **SMALL), TypeError, "camera must be a raylume.Camera"),
        (lambda: raylume.Session("seed").render(camera=5, **SMALL), TypeError, "camera must be a raylume.Camera"),
        (lambda: raylume.builtin_scene("seed").with_camera("front"), TypeError, "camera must be a raylume.Camera"),
        (lambda: raylume.Film(8, 8, "lanczos", total_spp=4), ValueError, "pixel_filter must be one of box"),
        (lambda: raylume.Film(0, 8, "box", total_spp=4), ValueError, "width must be a whole number, at least 1"),
        (lambda: raylume.Film(8, 8, "box", total_spp=2.5), ValueError, "total_spp must be a whole number"),
        (lambda: hash(raylume.builtin_scene("seed")), TypeError, "unhashable type: 'Scene'"),
    ],
    ids=["crop-2", "crop-text", "crop-float", "threads-float", "camera-str", "camera-int", "with_camera-str",
         "film-filter", "film-width", "film-spp", "hash"],
)  # fmt: skip
def test_bad_arguments_are_named_in_the_error(call, error, words):
    """Arguments of the wrong kind are refused in words that name them, not by whatever deep
    in the library first tripped over them (a tuple unpacking, Numba's thread setter, dict())."""
    with pytest.raises(error, match=words):
        call()


def test_add_samples_takes_whole_passes_only():
    """A pass of 0 or fewer samples, or not a whole number, is refused and leaves the film as it
    was: the passes after it still add up to the one-render image, bit for bit."""
    session = raylume.Session("seed")
    film = raylume.Film(24, 16, "box", total_spp=8)
    for bad in (-3, 0, 2.0, True):
        with pytest.raises(ValueError, match="spp must be a whole number of samples per pixel"):
            session.add_samples(film, bad, seed=1)
    session.add_samples(film, 8, seed=1)
    with pytest.raises(ValueError, match="8 are in and 3 more would exceed it"):
        session.add_samples(film, 3, seed=1)
    once = session.render(width=24, height=16, spp=8, seed=1, aovs=False)
    np.testing.assert_array_equal(film.rgb(), once.rgb)


def test_image_save_checks_exposure_and_takes_one_layer_name(tmp_path):
    """save's exposure is the scene's: a number of stops within +-64 (past it 2 ** exposure
    overflowed; NaN wrote a black image); `layers` may be one AOV name."""
    image = raylume.render("seed", width=24, height=16)
    for bad in (1e6, float("nan"), "2", True):
        with pytest.raises(ValueError, match="exposure must be a number of stops from -64 to 64"):
            image.save(tmp_path / "x.png", exposure=bad)
    assert not (tmp_path / "x.png").exists()
    image.save(tmp_path / "l.exr", layers="depth")
    import OpenEXR

    with OpenEXR.File(str(tmp_path / "l.exr"), separate_channels=True) as exr:
        channels = {name: c.pixels for name, c in exr.channels().items()}
    assert set(channels) == {"R", "G", "B", "depth.Z"}
    np.testing.assert_array_equal(channels["depth.Z"], image.aovs["depth"])
