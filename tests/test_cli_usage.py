"""What a newcomer meets first on the command line: usage errors in one line, warnings about
flags without effect, clean stderr in logs, the same exit status on Ctrl-C from render and view,
missing generated files, and `raylume warmup`."""

from __future__ import annotations

import re
import select
import signal
import subprocess
import sys
import time
import typing
from pathlib import Path

import pytest
import typer
from test_cli import GOOD_SCENE, assert_refused, raylume
from typer.testing import CliRunner

from raylume.cli import app

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def good(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(GOOD_SCENE)
    return path


def _typed_options():
    """(command, option) for every option of every command that takes a number: found from
    the commands themselves, so that a new one is covered too."""
    found = []
    for name, command in typer.main.get_command(app).commands.items():
        hints = typing.get_type_hints(command.callback)
        for param in command.params:
            kind = hints.get(param.name)
            if getattr(param, "is_flag", False) or kind is None:
                continue
            if set(typing.get_args(kind) or (kind,)) & {int, float}:
                found.append((name, param.opts[-1] if param.opts[-1].startswith("--") else param.opts[0]))
    return found


def test_every_typed_option_has_numbers():
    """The list below is not empty, and holds the ones a newcomer mistypes first."""
    assert {("render", "--spp"), ("render", "--width"), ("render", "--exposure"), ("view", "--port")} <= set(
        _typed_options()
    )


@pytest.mark.parametrize("command, option", _typed_options())
def test_a_value_that_is_no_number_is_one_line_and_exit_2(command, option):
    result = CliRunner().invoke(app, [command, option, "abc"])
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"raylume: error: {option} abc: "), result.stderr
    assert f"raylume {command} --help" in lines[0]


@pytest.mark.parametrize(
    "args, words",
    [
        (["render", "--bogus"], "No such option: --bogus"),
        (["render", "--spp"], "requires an argument"),
        (["bogus"], "No such command 'bogus'"),
        (["render", "a.toml", "b.toml"], "unexpected extra argument"),
    ],
)
def test_other_usage_errors_are_one_line_too(args, words):
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert len(result.stderr.splitlines()) == 1 and words in result.stderr, result.stderr
    assert "╭" not in result.stderr and "Usage:" not in result.stderr


def test_the_installed_command_answers_the_same(tmp_path):
    """The real entry point (a subprocess), not only the test runner's call."""
    result = raylume("render", "--spp", "abc", cwd=tmp_path)
    assert_refused(result, "raylume: error: --spp abc:")
    assert len(result.stderr.splitlines()) == 1, result.stderr


def test_denoise_outside_path_mode_is_warned_about(tmp_path, good):
    result = raylume("render", good, "-o", "out.png", "--denoise", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if line.startswith("raylume: warning:")]
    assert any("--denoise" in line and "trace mode" in line and "--mode path" in line for line in warnings), (
        result.stderr
    )
    plain = raylume("render", good, "-o", "out.png", cwd=tmp_path)
    assert "warning" not in plain.stderr, plain.stderr


def test_no_blank_lines_on_stderr_that_is_no_terminal(tmp_path, good):
    """A render long enough for the progress bar (over half a second), stderr a pipe: every
    line says something (Rich's bar, gone from a terminal, left an empty line in logs)."""
    result = raylume("render", good, "-o", "out.png", "--width", 1200, "--height", 1200, "--spp", 16, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    lines = result.stderr.splitlines()
    assert lines and all(line.strip() for line in lines), repr(result.stderr)


def test_a_missing_generated_file_names_its_script(tmp_path):
    """examples/forest.toml needs what examples/forest/make_forest.py writes: a fresh clone
    lacks it, and the error says what to run."""
    scene_dir = tmp_path / "example"
    (scene_dir / "forest").mkdir(parents=True)
    (scene_dir / "forest.toml").write_text((REPO / "examples" / "forest.toml").read_text())
    (scene_dir / "forest" / "make_forest.py").write_text((REPO / "examples" / "forest" / "make_forest.py").read_text())
    result = raylume("render", "forest.toml", cwd=scene_dir)
    assert_refused(result, "forest.toml", "does not exist", "python forest/make_forest.py")
    assert not (scene_dir / "render.png").exists()


def test_a_missing_density_grid_names_its_script(tmp_path):
    """examples/smoke.toml's grid is what examples/smoke/make_smoke.py writes."""
    scene_dir = tmp_path / "example"
    (scene_dir / "smoke").mkdir(parents=True)
    (scene_dir / "smoke.toml").write_text((REPO / "examples" / "smoke.toml").read_text())
    (scene_dir / "sky.hdr").write_bytes((REPO / "examples" / "sky.hdr").read_bytes())
    (scene_dir / "smoke" / "make_smoke.py").write_text((REPO / "examples" / "smoke" / "make_smoke.py").read_text())
    result = raylume("render", "smoke.toml", "--width", "16", "--height", "12", cwd=scene_dir)
    assert_refused(result, "smoke.toml", "no such file", "python smoke/make_smoke.py")
    assert not (scene_dir / "render.png").exists()


def test_view_exits_130_on_ctrl_c_as_render_does(tmp_path):
    """`raylume view` stopped by Ctrl-C (SIGINT) exits 130, `raylume render`'s status for it."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "raylume.cli", "view", "seed", "--width", "16", "--height", "12", "--port", "0",
         "--no-browser"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 120)
        assert ready, "raylume view printed no URL"
        assert proc.stdout.readline().startswith("raylume view: http://127.0.0.1:")
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 130, proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize(
    "scene, mode, words",
    [
        ("[[objects]]\ntype = 'sphere'\ncenter = [0, 0, 3]\nradius = 1\n", "trace", "the scene has no lights"),
        (
            "[[objects]]\ntype = 'sphere'\ncenter = [0, 0, 3]\nradius = 1\n[[lights]]\ntype = 'ambient'\n"
            "[media.fog]\ntype = 'homogeneous'\nsigma_s = 0.1\n[render]\nmedium = 'fog'\n",
            "raster",
            "participating media render in path mode only",
        ),
        (
            "[[objects]]\ntype = 'sphere'\ncenter = [0, 0, 3]\nradius = 1\n[render]\nnoise_threshold = 0.05\n",
            "cast",
            "the live view gives every pixel its spp",
        ),
    ],
)
def test_view_warns_as_render_does(tmp_path, scene, mode, words):
    """A scene `raylume render` warns about is warned about by `raylume view` too, in the same one
    line, once (its render thread's own warnings had come in Python's two-line format, and a
    view's trace passes had given no warning at all)."""
    (tmp_path / "s.toml").write_text(scene)
    proc = subprocess.Popen(
        [sys.executable, "-m", "raylume.cli", "view", "s.toml", "--mode", mode, "--width", "16", "--height", "12",
         "--port", "0", "--no-browser"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 120)
        assert ready, "raylume view printed no URL"
        proc.stdout.readline()
        time.sleep(2)  # a few passes of the render thread
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)
        stderr = proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    said = [line for line in stderr.splitlines() if words in line]
    assert len(said) == 1 and said[0].startswith("raylume: warning: "), stderr
    assert "SceneWarning" not in stderr and "Traceback" not in stderr, stderr


def test_warmup_is_a_command(tmp_path):
    result = CliRunner().invoke(app, ["warmup", "--help"])
    assert result.exit_code == 0 and "Compile every kernel" in result.output
    refused = CliRunner().invoke(app, ["warmup", "--processes", "0"])
    assert refused.exit_code == 2 and "--processes 0" in refused.stderr


def test_warmup_stopped_by_sigterm_stops_its_compiling_processes(tmp_path):
    """`raylume warmup` compiles in child processes (python -m raylume.warmup --part I/N): SIGTERM
    had ended the command at once and left them compiling for minutes, re-parented to init. An
    empty cache (XDG_CACHE_HOME) keeps them busy long enough; their --part arguments carry it."""
    import os

    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")}
    proc = subprocess.Popen([sys.executable, "-m", "raylume.cli", "warmup", "-j", "2"], env=env,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip

    def parts() -> list[str]:  # the warm-up's children: the ones whose environment has this cache
        found = []
        for environ in Path("/proc").glob("[0-9]*/environ"):
            try:
                if str(tmp_path / "cache").encode() in environ.read_bytes():
                    cmdline = (environ.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode()
                    found += [cmdline] if "raylume.warmup" in cmdline else []
            except OSError:
                continue
        return found

    deadline = time.monotonic() + 60
    while len(parts()) < 2 and time.monotonic() < deadline:
        time.sleep(0.2)
    assert len(parts()) == 2, parts()
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, stderr
    assert "raylume: warm-up interrupted" in stderr and "Traceback" not in stderr, stderr
    assert parts() == []
    refused = subprocess.run([sys.executable, "-m", "raylume.warmup", "--part", "1"], capture_output=True, text=True)
    assert refused.returncode == 2 and "--part 1: expected I/N" in refused.stderr and "Traceback" not in refused.stderr


def test_a_flag_given_twice_is_named_by_the_value_that_counts():
    """click keeps an option's last value, so the message quotes that one."""
    result = CliRunner().invoke(app, ["render", "--width", "32", "--width", "abc"])
    assert result.exit_code == 2
    assert result.stderr.startswith("raylume: error: --width abc: "), result.stderr


def test_a_required_option_left_out_is_named():
    result = CliRunner().invoke(app, ["convert", "seed"])
    assert result.exit_code == 2
    assert result.stderr.strip() == "raylume: error: Missing option '-o' / '--output'. (see raylume convert --help)"


def test_view_names_a_host_that_is_no_address():
    result = CliRunner().invoke(app, ["view", "seed", "--host", "999.1.1.1", "--port", "0", "--no-browser"])
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("raylume: error: --host 999.1.1.1: not an address"), lines


@pytest.mark.parametrize(
    "name, text, words",
    [
        # a transform that carries a mesh past float32's range: refused before numpy converts it
        (
            "scaled.toml",
            "[[objects]]\ntype = 'mesh'\nvertices = [[0, 0, 3], [1e30, 0, 3], [0, 1, 3]]\nfaces = [[0, 1, 2]]\n"
            "transform = { scale = 1e20 }\n",
            "scaled.toml: objects[0]: its coordinates reach 1e+50 in world space, beyond float32's range",
        ),
        (
            "sphere.toml",
            "[[objects]]\ntype = 'sphere'\ncenter = [0, 0, 3e38]\nradius = 1e38\n",
            "sphere.toml: objects[0]: its coordinates reach 4e+38 in world space",
        ),
        # a mesh file as the scene, framed by a camera its size would put out of range
        ("big.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n", "big.obj: its coordinates reach 1e+39"),
    ],
)
def test_geometry_beyond_float32_is_one_line_without_warnings(tmp_path, name, text, words):
    (tmp_path / name).write_text(text)
    result = raylume("render", name, "-o", "out.png", "--width", "16", "--height", "12", cwd=tmp_path)
    assert_refused(result, words)
    assert len(result.stderr.splitlines()) == 1, result.stderr
    assert not (tmp_path / "out.png").exists()


def test_help_shows_a_required_argument_by_its_name():
    """`raylume convert [OPTIONS] IN`, not Typer's `{IN}`; the command list keeps convert's summary whole."""
    usage = CliRunner().invoke(app, ["convert", "--help"], env={"COLUMNS": "100"}).output
    assert re.search(r"convert \[OPTIONS\] IN *\n", usage) and "{IN}" not in usage, usage
    assert ".pbrt" in usage
    listing = CliRunner().invoke(app, ["--help"], env={"COLUMNS": "100"}).output
    assert "convert  Write IN as a raylume scene file that renders the same image as IN." in listing, listing
