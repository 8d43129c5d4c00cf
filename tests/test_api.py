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
