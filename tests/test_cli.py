"""The `raylume` command end to end, as a subprocess: outputs, stats, AOVs, exit codes, no litter."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image as PILImage

GOOD_SCENE = """
[render]
width = 24
height = 16
[[lights]]
type = "point"
position = [0, 3, 0]
intensity = 0.8
[[objects]]
type = "sphere"
center = [0, 0, 3]
radius = 1
material = { color = [1, 0, 0], specular = 50 }
"""


def raylume(*args, cwd, env=None):
    env = {**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})}
    return subprocess.run(
        [sys.executable, "-m", "raylume.cli", *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
    )


def assert_refused(result, *words):
    """The bad-input contract: exit status 2, a message naming each of `words`, no traceback."""
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    for word in words:
        assert word in result.stderr, (word, result.stderr)


@pytest.fixture
def good(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(GOOD_SCENE)
    return path


def test_no_arguments_renders_the_seed_scene_to_render_png(tmp_path):
    result = raylume("render", "--width", 60, "--height", 60, "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    image = np.asarray(PILImage.open(tmp_path / "render.png"))
    assert image.shape == (60, 60, 3)
    assert image[0].max() == 0  # black sky
    assert image[40:, :, 0].mean() > 100  # red sphere and yellow ground


def test_outputs_stats_and_aovs(tmp_path, good):
    result = raylume(
        "render",
        good,
        "-o",
        "out.npy",
        "--stats",
        "stats.json",
        "--aov",
        "depth=d.npy",
        "--aov",
        "normal=n.npy",
        "--aov",
        "object=o.npy",
        "--aov",
        "prim=p.npy",
        "--quiet",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    rgb = np.load(tmp_path / "out.npy")
    assert rgb.dtype == np.float32 and rgb.shape == (16, 24, 3)
    depth, normal = np.load(tmp_path / "d.npy"), np.load(tmp_path / "n.npy")
    obj, prim = np.load(tmp_path / "o.npy"), np.load(tmp_path / "p.npy")
    assert depth.dtype == np.float32 and depth.shape == (16, 24)
    assert normal.dtype == np.float32 and normal.shape == (16, 24, 3)
    assert obj.dtype == np.int32 and prim.dtype == np.int32
    hit = obj == 0
    assert hit.any() and (~hit).any()
    assert np.isinf(depth[~hit]).all() and (prim[~hit] == -1).all() and (prim[hit] == 0).all()
    assert depth[hit].min() == pytest.approx(2.0, abs=0.02)  # sphere front at z = 2
    np.testing.assert_allclose(np.linalg.norm(normal[hit], axis=-1), 1, atol=1e-5)
    assert (normal[hit][:, 2] < 0).all()  # faces the camera
    stats = json.loads((tmp_path / "stats.json").read_text())
    for key in (
        "width",
        "height",
        "spp",
        "mode",
        "threads",
        "primitives",
        "triangles",
        "rays",
        "primary_rays",
        "build_seconds",
        "render_seconds",
        "mrays_per_second",
        "bvh_nodes",
        "bvh_bytes",
        "parse_seconds",
        "mesh_load_seconds",
        "compile_seconds",
    ):
        assert key in stats, key
    assert stats["compile_seconds"] >= 0 and stats["mesh_load_seconds"] == 0 and stats["parse_seconds"] > 0
    assert stats["primary_rays"] == 16 * 24 and stats["rays"] > stats["primary_rays"]
    assert stats["primitives"] == 1 and stats["triangles"] == 0 and stats["mode"] == "trace"


def test_flags_override_the_scene_render_table(tmp_path, good):
    result = raylume("render", good, "--width", 10, "--height", 5, "--mode", "cast", "-o", "c.npy", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    rgb = np.load(tmp_path / "c.npy")
    assert rgb.shape == (5, 10, 3)
    assert set(np.unique(rgb[..., 0])) <= {0.0, 1.0}  # cast: unlit colour or background


def test_scenes_lists_builtins(tmp_path):
    result = raylume("scenes", cwd=tmp_path)
    assert result.returncode == 0
    assert "seed" in result.stdout and "(default)" in result.stdout


BAD_SCENES = {
    "radius.toml": ('[[objects]]\ntype = "sphere"\ncenter = [0, 0, 3]\nradius = -2\n', "objects[0].radius"),
    "syntax.toml": ("[render\nwidth = 3\n", "line 1"),
    "unknown.toml": ("[camera]\nfov = 40\nzoom = 2\n", "camera.zoom"),
    "material.json": (
        '{"objects": [{"type": "sphere", "center": [0,0,3], "radius": 1, "material": "x"}]}',
        "objects[0].material",
    ),
    "mesh.toml": ('[[objects]]\ntype = "mesh"\nfile = "missing.obj"\n', "objects[0].file"),
}


@pytest.mark.parametrize("name", sorted(BAD_SCENES))
def test_bad_scene_exits_2_with_message_and_writes_nothing(tmp_path, name):
    text, key = BAD_SCENES[name]
    (tmp_path / name).write_text(text)
    result = raylume("render", name, "-o", "out.png", "--stats", "s.json", cwd=tmp_path)
    assert_refused(result, name, key)
    assert not (tmp_path / "out.png").exists() and not (tmp_path / "s.json").exists()


@pytest.mark.parametrize(
    "args, words",
    [
        (["--width", "0"], "--width"),
        (["--mode", "photon"], "--mode"),
        (["--spp", "abc"], "spp"),
        (["-o", "out.gif"], "unknown output format"),
        (["-o", "out.avi"], "use one of .png, .jpg, .jpeg, .npy, .exr, .hdr; for an animation .mp4, .gif, or frames"),
        (["-o", "missing/out.png"], "does not exist"),
        (["--aov", "color=c.npy"], "unknown AOV"),
        (["--aov", "depth"], "NAME=PATH"),
        (["--threads", "0"], "--threads"),
        (["no_such_builtin"], "not a scene file"),
    ],
)
def test_bad_flags_exit_2(tmp_path, args, words):
    result = raylume("render", *args, cwd=tmp_path)
    assert_refused(result, words)
    assert not (tmp_path / "render.png").exists()


def test_existing_output_is_untouched_on_error(tmp_path, good):
    out = tmp_path / "keep.png"
    out.write_bytes(b"precious")
    (tmp_path / "bad.toml").write_text("[render]\nwidth = -1\n")
    assert raylume("render", "bad.toml", "-o", out, cwd=tmp_path).returncode == 2
    assert out.read_bytes() == b"precious"
    # and a good render replaces it completely, leaving no temporary files behind
    assert raylume("render", good, "-o", out, "-q", cwd=tmp_path).returncode == 0
    assert PILImage.open(out).size == (24, 16)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml", "keep.png", "scene.toml"]


def test_output_may_not_overwrite_the_scene(tmp_path, good):
    result = raylume("render", "scene.toml", "--aov", "depth=scene.npy", "-o", "scene.npy", cwd=tmp_path)
    assert result.returncode == 2
    assert good.read_text() == GOOD_SCENE


# Every scene-file entry of the catalogue of bad inputs (docs/errors.md), end to end.
from test_scene_load import BAD as BAD_DOCUMENTS  # noqa: E402


@pytest.mark.parametrize("document, key, words", BAD_DOCUMENTS, ids=[b[1] + ":" + b[2][:12] for b in BAD_DOCUMENTS])
def test_catalogue_of_bad_scene_files_end_to_end(tmp_path, document, key, words):
    (tmp_path / "bad.json").write_text(json.dumps(document))
    result = raylume("render", "bad.json", "-o", "out.png", "--stats", "s.json", cwd=tmp_path)
    assert_refused(result, "bad.json", key, words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json"]


BAD_MESHES = {
    "empty.obj": ("", "empty"),
    "points.ply": (
        (
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
            "end_header\n0 0 0\n1 1 1\n"
        ),
        "no triangles",
    ),
    "range.obj": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", ""),
    "nan.obj": ("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", ""),
    "notply.ply": ("this is not a ply file at all\n", ""),
}


@pytest.mark.parametrize("name", sorted(BAD_MESHES))
def test_catalogue_of_bad_meshes_end_to_end(tmp_path, name):
    text, words = BAD_MESHES[name]
    (tmp_path / name).write_text(text)
    (tmp_path / "scene.toml").write_text(f'[[objects]]\ntype = "mesh"\nfile = "{name}"\n')
    result = raylume("render", "scene.toml", "-o", "out.png", cwd=tmp_path)
    assert_refused(result, "objects[0].file", name, words)
    assert not (tmp_path / "out.png").exists()


def test_mesh_folder_instead_of_file_end_to_end(tmp_path):
    (tmp_path / "dir.obj").mkdir()
    (tmp_path / "scene.toml").write_text('[[objects]]\ntype = "mesh"\nfile = "dir.obj"\n')
    assert_refused(raylume("render", "scene.toml", cwd=tmp_path), "dir.obj")


def test_debug_shows_the_traceback(tmp_path):
    (tmp_path / "bad.toml").write_text("[render]\nwidth = -1\n")
    result = raylume("render", "bad.toml", "--debug", cwd=tmp_path)
    assert result.returncode != 0 and "Traceback" in result.stderr


# ---------------------------------------------------------------- help, version, scenes


def test_render_help_shows_flags_as_flags_and_metavars_in_words(tmp_path):
    result = raylume("render", "--help", cwd=tmp_path, env={"COLUMNS": "200"})
    assert result.returncode == 0, result.stderr
    text = result.stdout
    for noise in ("<bool>", "<list[str]>", "<str>", "<int>"):
        assert noise not in text, (noise, text)
    for word in ("--quiet", "--help", "--aov", "NAME=PATH", "--set", "KEY=VALUE", "--bit-depth"):
        assert word in text, (word, text)


def test_version_prints_the_package_version(tmp_path):
    import raylume as package

    result = raylume("--version", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == f"raylume {package.__version__}"


def test_bare_command_prints_the_help(tmp_path):
    result = raylume(cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Missing command" not in result.stdout + result.stderr
    assert "Usage" in result.stdout and "render" in result.stdout and "scenes" in result.stdout


def test_scenes_prints_whole_descriptions(tmp_path):
    from raylume.scene.builtin import builtin_names, builtin_path

    result = raylume("scenes", cwd=tmp_path, env={"COLUMNS": "200"})
    assert result.returncode == 0, result.stderr
    flat = " ".join(result.stdout.split())
    for name in builtin_names():
        comment = []
        for line in builtin_path(name).read_text().splitlines():
            if not line.startswith("#"):
                break
            comment.append(line.lstrip("#").strip())
        assert " ".join(" ".join(comment).split()) in flat, (name, result.stdout)


# ---------------------------------------------------------------- outputs checked before rendering


def test_output_that_is_a_folder_says_so(tmp_path):
    (tmp_path / "adir").mkdir()
    result = raylume("render", "-o", "adir", cwd=tmp_path)
    assert_refused(result, "adir", "folder", ".png")
    assert "(none)" not in result.stderr


def _unwritable_folder() -> str:
    """A folder this process cannot create files in (root can write almost anywhere)."""
    for folder in ("/sys", "/proc/sys"):
        if os.path.isdir(folder):
            try:
                fd = os.open(os.path.join(folder, ".raylume-probe"), os.O_CREAT | os.O_WRONLY, 0o600)
            except OSError:
                return folder
            os.close(fd)
            os.unlink(os.path.join(folder, ".raylume-probe"))
    pytest.skip("no unwritable folder on this machine")


@pytest.mark.parametrize("flag, name", [("-o", "o.png"), ("--aov", "depth=d.npy"), ("--stats", "s.json")])
def test_unwritable_output_is_refused_before_rendering(tmp_path, good, flag, name):
    folder = _unwritable_folder()
    value = f"depth={folder}/d.npy" if flag == "--aov" else f"{folder}/{name}"
    args = ["-o", "out.png"] if flag != "-o" else []
    result = raylume("render", good, *args, flag, value, "-q", cwd=tmp_path)
    assert_refused(result, folder, "cannot write")
    for noise in ("PermissionError", "OSError", ".part", "Errno"):
        assert noise not in result.stderr, (noise, result.stderr)
    assert not (tmp_path / "out.png").exists()  # refused before rendering anything


# ---------------------------------------------------------------- warnings, summary


def test_ignored_exposure_and_filter_are_warned_about(tmp_path, good):
    result = raylume("render", good, "-o", "out.npy", "--exposure", 1, "--filter", "gaussian", "--spp", 1, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if "warning" in line]
    assert any("--exposure" in line and "out.npy" in line for line in warnings), result.stderr
    assert any("--filter" in line and "spp" in line for line in warnings), result.stderr
    quiet = raylume("render", good, "-o", "out.png", "--exposure", 1, "--filter", "gaussian", "--spp", 4, cwd=tmp_path)
    assert quiet.returncode == 0 and "warning" not in quiet.stderr, quiet.stderr


def test_raster_summary_does_not_report_rays(tmp_path, good):
    result = raylume("render", good, "--mode", "raster", "-o", "r.png", "--stats", "s.json", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Mrays" not in result.stderr and "rasterized" in result.stderr, result.stderr
    # the rasterizer builds no BVH, and its stats say so
    stats = json.loads((tmp_path / "s.json").read_text())
    assert (stats["bvh_nodes"], stats["bvh_bytes"], stats["rays"]) == (0, 0, 0), stats


def test_summary_reports_compilation_apart_from_the_build(tmp_path, good):
    result = raylume("render", good, "-o", "r.png", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    summary = result.stderr.strip().splitlines()[-1]
    assert ", build " in summary and ", compile " in summary, result.stderr


def _notice(terminal: bool):
    import io

    from rich.console import Console

    from raylume.cli import _compile_notice

    out = io.StringIO()
    return _compile_notice(False, Console(file=out, force_terminal=terminal, width=80)), out


@pytest.mark.parametrize("terminal", [True, False])
def test_compile_notice_shows_only_when_the_warm_up_is_slow(terminal):
    import time

    from raylume.cli import NOTICE_AFTER, compiling_notice

    notice, out = _notice(terminal)
    with notice as status:
        status("compiling")
        status("rendering")  # loaded from the cache: well under NOTICE_AFTER
        time.sleep(NOTICE_AFTER + 0.3)
    assert out.getvalue() == ""
    notice, out = _notice(terminal)
    with notice as status:
        status("compiling")
        time.sleep(NOTICE_AFTER + 0.5)  # compiling
        status("rendering")
    # what compiles, and that it happens once per mode and kind of scene
    assert compiling_notice("compiling", "trace") in " ".join(out.getvalue().split())
    assert "trace-mode kernels" in compiling_notice("compiling", "trace") and "once per mode and kind of scene" in (
        compiling_notice("compiling", "trace")
    )
    assert notice.spinner is None and notice.timer is None  # stopped once the kernels are ready
    notice, out = _notice(terminal)
    with notice as status:
        status("compiling")
    time.sleep(NOTICE_AFTER + 0.3)  # Ctrl-C during compilation: the context ends, so does the timer
    assert out.getvalue() == ""


def test_quiet_shows_no_compile_notice():
    from raylume.cli import _compile_notice

    with _compile_notice(True) as status:
        status("compiling the path-mode kernels")  # (still called: it checks for a swallowed Ctrl-C)
        assert status.__self__.timer is None and status.__self__.spinner is None


def test_a_ctrl_c_during_an_import_waits_for_it_and_stops_the_render(tmp_path, monkeypatch):
    """trimesh's optional imports catch BaseException: a Ctrl-C while they ran (reading a mesh
    file the first time) was lost, and the render went on to write its image with exit 0, or it
    broke trimesh, whose import then failed with a traceback. The Ctrl-C now waits for the import
    to end, which stays whole, and stops the render at its next stage."""
    import importlib

    from typer.testing import CliRunner

    import raylume.cli as cli

    (tmp_path / "greedy_library.py").write_text(
        "import signal\n"
        "try:\n"
        "    signal.raise_signal(signal.SIGINT)  # Ctrl-C while a library imports its optional parts ...\n"
        "except BaseException:  # ... which catch everything, as trimesh's do\n"
        "    SWALLOWED = True\n"
        "else:\n"
        "    SWALLOWED = False\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    resolve = cli._resolve_scene
    imported = {}

    def importing(*args, **kwargs):
        imported["module"] = importlib.import_module("greedy_library")
        return resolve(*args, **kwargs)

    monkeypatch.setattr(cli, "_resolve_scene", importing)
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli.app, ["render", "--width", "8", "--height", "8"])
    assert result.exit_code == 130, result.output
    assert "interrupted; nothing written" in result.output and not (tmp_path / "render.png").exists()
    assert imported["module"].SWALLOWED is False  # the import ran whole


@pytest.mark.parametrize("broken", [TypeError, ValueError])
def test_what_a_swallowed_ctrl_c_breaks_is_the_ctrl_c(tmp_path, monkeypatch, broken):
    """The library that swallowed the Ctrl-C may then fail itself (trimesh's import, its optional
    module replaced by a wrapper of the KeyboardInterrupt, failed a line later with a TypeError:
    a traceback and exit 1); and a Ctrl-C that lands in a ctypes callback (Numba loading kernels)
    was printed as 8 lines of "Exception ignored"."""
    import signal
    import types

    from typer.testing import CliRunner

    import raylume.cli as cli

    def swallowing_then_failing(*args, **kwargs):
        try:
            signal.raise_signal(signal.SIGINT)
        except BaseException:
            pass
        sys.unraisablehook(
            types.SimpleNamespace(
                exc_type=KeyboardInterrupt, exc_value=KeyboardInterrupt(), exc_traceback=None, object=None,
                err_msg="Exception ignored on calling ctypes callback function",
            )
        )  # fmt: skip
        raise broken("unsupported operand type(s) for |: 'ExceptionWrapper' and 'NoneType'")

    monkeypatch.setattr(cli, "_resolve_scene", swallowing_then_failing)
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli.app, ["render", "--width", "8", "--height", "8"])
    assert result.exit_code == 130, result.output
    assert result.output.strip() == "raylume: interrupted; nothing written"


def test_a_ctrl_c_after_the_image_is_written_says_so(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    import raylume.cli as cli
    import raylume.image

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(raylume.image, "save_npy", interrupted)  # Ctrl-C while the AOVs are written
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli.app, ["render", "--width", "8", "--height", "8", "--aov", "depth=d.npy"])
    assert result.exit_code == 130 and (tmp_path / "render.png").exists()
    assert result.output.strip() == "raylume: interrupted after writing render.png; nothing more"


# ---------------------------------------------------------------- --set, new formats, EXR layers


def test_set_overrides_scene_keys(tmp_path, good):
    result = raylume(
        "render",
        good,
        "--set",
        "render.width=12",
        "--set",
        "camera.position=[0, 0, -1]",
        "--set",
        "render.mode=cast",
        "--set",
        'objects.0.material.color="#00ff00"',
        "-o",
        "out.npy",
        "-q",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    rgb = np.load(tmp_path / "out.npy")
    assert rgb.shape == (16, 12, 3)
    assert set(np.unique(rgb[..., 1])) == {0.0, 1.0} and rgb[..., 0].max() == 0  # cast, now green


def test_set_also_applies_to_builtin_scenes(tmp_path):
    result = raylume(
        "render",
        "--set",
        "render.width=9",
        "--set",
        "render.height=7",
        "--set",
        "render.mode=cast",
        "-o",
        "out.npy",
        "-q",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    assert np.load(tmp_path / "out.npy").shape == (7, 9, 3)


@pytest.mark.parametrize(
    "assignment, words",
    [
        ("objects.5.radius=1", ["objects.5", "out of range"]),
        ("objects.0.radius=-1", ["objects[0].radius", "--set objects.0.radius=-1"]),
        ("camera.zoom=2", ["camera.zoom", "unknown key"]),
        ("render.width.x=3", ["render.width"]),
        ("nokey", ["KEY=VALUE"]),
    ],
)
def test_bad_set_is_refused_naming_the_key_path(tmp_path, good, assignment, words):
    result = raylume("render", good, "--set", assignment, "-o", "out.png", cwd=tmp_path)
    assert_refused(result, *words)
    assert not (tmp_path / "out.png").exists()


def test_jpeg_and_16_bit_png_outputs(tmp_path, good):
    for args in (["-o", "out.jpg"], ["-o", "out.jpeg"], ["-o", "out16.png", "--bit-depth", 16]):
        result = raylume("render", good, *args, "-q", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
    assert PILImage.open(tmp_path / "out.jpg").format == "JPEG"
    assert PILImage.open(tmp_path / "out.jpeg").size == (24, 16)
    assert (tmp_path / "out16.png").read_bytes()[24] == 16  # IHDR bit depth
    assert_refused(raylume("render", good, "-o", "out.jpg", "--bit-depth", 16, cwd=tmp_path), "--bit-depth", ".png")


def test_aovs_as_layers_of_one_exr(tmp_path, good):
    OpenEXR = pytest.importorskip("OpenEXR")
    result = raylume(
        "render",
        good,
        "-o",
        "out.exr",
        *[a for n in ("depth", "normal", "albedo", "object", "prim") for a in ("--aov", n)],
        "-q",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    with OpenEXR.File(str(tmp_path / "out.exr"), separate_channels=True) as f:
        ch = {name: c.pixels for name, c in f.channels().items()}
    assert set(ch) == {
        "R",
        "G",
        "B",
        "depth.Z",
        "normal.X",
        "normal.Y",
        "normal.Z",
        "albedo.R",
        "albedo.G",
        "albedo.B",
        "object.id",
        "prim.id",
    }
    obj = ch["object.id"].view(np.int32)
    prim = ch["prim.id"].view(np.int32)
    hit = obj == 0
    assert hit.any() and (obj[~hit] == -1).all() and (prim[~hit] == -1).all() and (prim[hit] == 0).all()
    assert np.isinf(ch["depth.Z"][~hit]).all() and ch["depth.Z"][hit].min() == pytest.approx(2.0, abs=0.02)
    assert (ch["normal.Z"][hit] < 0).all()
    assert ch["albedo.R"][hit].max() == pytest.approx(1.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.exr", "scene.toml"]


def test_aov_without_path_needs_an_exr_output(tmp_path, good):
    assert_refused(
        raylume("render", good, "-o", "out.png", "--aov", "depth", cwd=tmp_path), "--aov depth", ".exr", "NAME=PATH"
    )


def test_flags_without_effect_on_the_render_are_warned_about(tmp_path):
    """A flag given where it does nothing says so in one line (--integrator had said nothing)."""
    result = raylume("render", "--mode", "cast", "--width", 8, "--height", 6, "--denoise", "--integrator", "bdpt",
                     "-o", "c.png", "-q", cwd=tmp_path)  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stderr.splitlines() == [
        "raylume: warning: --denoise has no effect in cast mode: it denoises path-traced images (--mode path)",
        "raylume: warning: --integrator has no effect in cast mode: it picks path mode's (--mode path)",
    ]
    result = raylume("render", "--mode", "raster", "--width", 8, "--height", 6, "--filter", "gaussian", "-o", "r.png",
                     "-q", cwd=tmp_path)  # fmt: skip
    assert "--filter has no effect in raster mode" in result.stderr and result.returncode == 0


def test_one_aov_given_two_files_is_refused(tmp_path, good):
    """Only the last had been written, without a word."""
    result = raylume("render", good, "-o", "o.png", "--aov", "depth=a.npy", "--aov", "depth=b.npy", cwd=tmp_path)
    assert_refused(result, "--aov depth=b.npy", "a.npy names the depth AOV's file already")
    assert not (tmp_path / "o.png").exists()


def test_crop_writes_that_window_of_the_full_render(tmp_path):
    full = raylume("render", "--width", 60, "--height", 40, "--spp", 2, "-o", "full.npy", "--aov", "depth=fd.npy",
                   cwd=tmp_path)  # fmt: skip
    assert full.returncode == 0, full.stderr
    part = raylume("render", "--width", 60, "--height", 40, "--spp", 2, "--crop", "10:35,5:30", "-o", "part.npy",
                   "--aov", "depth=pd.npy", cwd=tmp_path)  # fmt: skip
    assert part.returncode == 0, part.stderr
    assert "part.npy: 25x25 window of 60x40 trace" in part.stdout + part.stderr  # the size of what is written
    want = np.load(tmp_path / "full.npy")[5:30, 10:35]
    got = np.load(tmp_path / "part.npy")
    assert got.shape == (25, 25, 3) and got.tobytes() == np.ascontiguousarray(want).tobytes()
    assert np.array_equal(np.load(tmp_path / "pd.npy"), np.load(tmp_path / "fd.npy")[5:30, 10:35])


@pytest.mark.parametrize("crop", ["10:5,0:10", "0:61,0:10", "a:b,c:d", "0:10"])
def test_bad_crops_are_refused_before_rendering(tmp_path, crop):
    result = raylume("render", "--width", 60, "--height", 40, "--crop", crop, cwd=tmp_path)
    assert_refused(result, "crop")
    assert not (tmp_path / "render.png").exists()


def test_a_path_scene_of_unlimited_depth_previews_in_cast_and_raster_mode(tmp_path):
    """max_depth -1 (path mode's unlimited) was refused by --mode cast and raster, which trace no
    bounces, and trace mode's refusal blamed the command line, not the file's key."""
    scene = tmp_path / "scene.toml"
    scene.write_text(
        '[render]\nwidth = 8\nheight = 8\nmode = "path"\nmax_depth = -1\n'
        '[[lights]]\ntype = "ambient"\n[[objects]]\ntype = "sphere"\ncenter = [0, 0, 3]\nradius = 1\n'
    )
    for mode in ("cast", "raster"):
        result = raylume("render", scene, "--mode", mode, "-o", f"{mode}.png", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
    (tmp_path / "trace.png").write_bytes(b"keep")
    result = raylume("render", scene, "--mode", "trace", "-o", "trace.png", cwd=tmp_path)
    assert_refused(result, "scene.toml: render.max_depth: -1", "--max-depth N")
    assert (tmp_path / "trace.png").read_bytes() == b"keep"
    assert raylume("render", scene, "--mode", "trace", "--max-depth", 2, "-o", "t.png", cwd=tmp_path).returncode == 0
