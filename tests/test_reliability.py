"""Robustness: interrupts, determinism across threads, scale-independent ray offsets, NaN-free
images for random scenes, loader fuzzing, memory checks."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import raylume
from raylume.errors import RaylumeError, SceneError
from raylume.render import check_memory

QUALITY = Path(__file__).resolve().parents[1] / "examples" / "quality.toml"


def _warm_kernels(tmp_path):
    """Compile (or load) the kernels first, so the interrupt lands in the render itself."""
    subprocess.run(
        [
            sys.executable,
            "-m",
            "raylume.cli",
            "render",
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "16",
            "-o",
            str(tmp_path.parent / "warm.png"),
            "-q",
        ],
        check=True,
    )


def _watch(stream, text: bytes) -> tuple[threading.Event, list]:
    """Read `stream` in a thread; the event is set once `text` has appeared in it."""
    seen, chunks = threading.Event(), []

    def read():
        while chunk := os.read(stream.fileno(), 4096):
            chunks.append(chunk)
            if text in b"".join(chunks):
                seen.set()

    threading.Thread(target=read, daemon=True).start()
    return seen, chunks


def _sigint_as_in_a_terminal() -> None:
    """In the child before it runs Python: SIGINT's default action, as a command typed in a
    terminal has. An ignored SIGINT is inherited, and Python then leaves it ignored: a test run
    started in the background by a non-interactive shell (`make test &`) ignores SIGINT, and
    these renders ran to their end."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _render_in_progress(tmp_path, *args):
    """`raylume render *args` in tmp_path, returned once its progress bar says it is rendering
    (not after a fixed sleep: on a loaded machine the import alone took over 5 s, and the
    interrupt landed in it), with the list its stderr is read into."""
    env = {**os.environ, "TTY_COMPATIBLE": "1", "TTY_INTERACTIVE": "1"}  # Rich draws its bar into the pipe
    proc = subprocess.Popen(
        [sys.executable, "-m", "raylume.cli", "render", *args],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env=env,
        preexec_fn=_sigint_as_in_a_terminal,
    )
    seen, chunks = _watch(proc.stderr, b"rendering")
    if not seen.wait(timeout=120):
        proc.kill()
        pytest.fail(b"".join(chunks).decode(errors="replace"))
    return proc, chunks


def _interrupted(proc, chunks) -> tuple[float, str]:
    """Send SIGINT; (seconds until the process ended, its stderr)."""
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=30)
    finally:
        proc.kill()
    elapsed = time.monotonic() - sent
    time.sleep(0.1)  # the reader thread's last chunk
    return elapsed, b"".join(chunks).decode(errors="replace")


def test_sigint_stops_quickly_writes_nothing_and_exits_130(tmp_path):
    _warm_kernels(tmp_path)
    proc, chunks = _render_in_progress(tmp_path, "--width", "4000", "--height", "4000", "--spp", "16", "-o", "big.png")
    time.sleep(1.0)  # inside the render's rows
    assert proc.poll() is None, "the render ended before the interrupt"
    elapsed, err = _interrupted(proc, chunks)
    assert proc.returncode == 130, err
    assert elapsed < 5
    assert "interrupted" in err and "Traceback" not in err
    assert not (tmp_path / "big.png").exists()
    assert list(tmp_path.iterdir()) == []


def test_sigint_with_partial_saves_the_rows_done(tmp_path):
    _warm_kernels(tmp_path)
    args = ("--width", "3000", "--height", "3000", "--spp", "16", "-o", "big.npy", "--partial")
    proc, chunks = _render_in_progress(tmp_path, *args)
    time.sleep(1.0)
    _, err = _interrupted(proc, chunks)
    assert proc.returncode == 130, err
    assert not (tmp_path / "big.npy").exists()
    partial = np.load(tmp_path / "big.partial.npy")
    assert partial.shape == (3000, 3000, 3)
    assert partial[-1].max() == 0.0  # the bottom rows (ground) were not reached


def test_sigint_during_a_long_render_exits_130_within_two_seconds(tmp_path):
    """Ctrl-C once the progress bar shows, on a render of several seconds (quality.toml, 16 spp,
    one thread): the lanes check a stop flag before every row, so the command ends at once."""
    command = [sys.executable, "-m", "raylume.cli", "render", str(QUALITY), "--threads", "1"]
    (tmp_path / "warm").mkdir()
    subprocess.run(
        [*command, "--width", "16", "--height", "10", "-o", "warm.png", "-q"], cwd=tmp_path / "warm", check=True
    )
    (tmp_path / "run").mkdir()
    proc, chunks = _render_in_progress(tmp_path / "run", str(QUALITY), "--threads", "1", "--spp", "16", "-o", "q.png")
    time.sleep(0.3)  # well inside the render's rows
    assert proc.poll() is None, "the render ended before the interrupt"
    elapsed, err = _interrupted(proc, chunks)
    print(f"Ctrl-C to exit: {elapsed:.3f} s")
    assert proc.returncode == 130, err
    assert elapsed < 2.0, elapsed
    assert "interrupted; nothing written" in err and "Traceback" not in err
    assert list((tmp_path / "run").iterdir()) == []


@pytest.mark.parametrize("mode", ["trace", "cast"])
@pytest.mark.parametrize("height", [48, 7, 1])  # lanes claim rows as they go: odd counts, fewer rows than lanes
def test_same_image_whatever_the_thread_count(mode, height):
    doc = raylume.builtin_scene("seed").model_dump()
    doc["render"]["background"] = [0.1, 0.2, 0.3]  # so that every row has something to show
    scene = raylume.scene_from_dict(doc)
    a = raylume.render(scene, width=64, height=height, spp=4, threads=1, mode=mode)
    assert a.rgb.shape == (height, 64, 3) and (a.rgb.max(axis=(1, 2)) > 0).all()  # every row rendered
    b = raylume.render(scene, width=64, height=height, spp=4, threads=2, mode=mode)
    np.testing.assert_array_equal(a.rgb, b.rgb)
    for name in a.aovs:
        np.testing.assert_array_equal(a.aovs[name], b.aovs[name])
    assert a.stats["rays"] == b.stats["rays"]  # each row traced once


def _scaled_seed(scale: float) -> raylume.Scene:
    doc = raylume.builtin_scene("seed").model_dump()
    for obj in doc["objects"]:
        obj["center"] = [c * scale for c in obj["center"]]
        obj["radius"] *= scale
    for light in doc["lights"]:
        if light["type"] == "point":
            light["position"] = [c * scale for c in light["position"]]
    doc["render"].update(width=48, height=48)
    return raylume.scene_from_dict(doc)


@pytest.mark.parametrize("scale", [1e-3, 1e4])
def test_no_acne_at_any_scene_scale(scale):
    """Scaling the whole scene (camera at the origin) must not change the image: offsets of
    secondary rays follow the hit's magnitude, so no self-shadowing speckles appear."""
    reference = raylume.render(_scaled_seed(1.0)).rgb
    scaled = raylume.render(_scaled_seed(scale)).rgb
    assert np.isfinite(scaled).all()
    close = np.abs(scaled - reference).max(axis=2) < 1e-3
    assert close.mean() > 0.995


def test_buffers_that_cannot_fit_are_refused_before_allocating(monkeypatch):
    session_module = sys.modules["raylume.session"]
    monkeypatch.setattr(session_module, "available_bytes", lambda: 1 << 30)
    with pytest.raises(RaylumeError, match="GiB of image buffers"):
        check_memory(16384, 16384, True)
    check_memory(600, 600, True)


# --- fuzzing --------------------------------------------------------------------------------

finite = st.floats(-50, 50, allow_nan=False)
vec = st.lists(finite, min_size=3, max_size=3)
colour = st.lists(st.floats(0, 1), min_size=3, max_size=3)
material = st.fixed_dictionaries(
    {"color": colour},
    optional={
        "specular": st.floats(1, 1000),
        "reflective": st.floats(0, 0.5),
        "transparency": st.floats(0, 0.5),
        "ior": st.floats(0.5, 3),
        "absorption": st.lists(st.floats(0, 5), min_size=3, max_size=3),
    },
)
sphere = st.fixed_dictionaries(
    {"type": st.just("sphere"), "center": vec, "radius": st.floats(0.01, 20), "material": material}
)
plane = st.fixed_dictionaries(
    {"type": st.just("plane"), "point": vec, "normal": vec.filter(lambda v: any(v)), "material": material}
)
triangle = st.fixed_dictionaries(
    {"type": st.just("triangle"), "vertices": st.lists(vec, min_size=3, max_size=3), "material": material}
)
light = st.one_of(
    st.fixed_dictionaries({"type": st.just("ambient"), "intensity": st.floats(0, 1)}),
    st.fixed_dictionaries({"type": st.just("point"), "position": vec, "intensity": st.floats(0, 2)}),
    st.fixed_dictionaries(
        {"type": st.just("directional"), "direction": vec.filter(lambda v: any(v)), "intensity": st.floats(0, 2)}
    ),
)
scene_doc = st.fixed_dictionaries(
    {
        "render": st.fixed_dictionaries(
            {
                "width": st.integers(1, 12),
                "height": st.integers(1, 12),
                "max_depth": st.integers(0, 6),
                "mode": st.sampled_from(["cast", "trace"]),
            }
        ),
        "lights": st.lists(light, max_size=4),
        "objects": st.lists(st.one_of(sphere, plane, triangle), max_size=6),
    }
)


@pytest.mark.filterwarnings("ignore::raylume.scene.checks.SceneWarning")  # random scenes may lack lights
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scene_doc)
def test_random_scenes_render_without_nan(doc):
    try:
        scene = raylume.scene_from_dict(doc)
    except SceneError:
        return  # e.g. a random triangle with collinear vertices: a clear error is the answer
    image = raylume.render(scene)
    assert np.isfinite(image.rgb).all() and image.rgb.min() >= 0
    depth = image.aovs["depth"]
    assert not np.isnan(depth).any() and np.isfinite(image.aovs["normal"]).all()
    json.dumps({k: v for k, v in image.stats.items()}, default=float)


json_value = st.recursive(
    st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=20,
)


@settings(max_examples=200, deadline=None)
@given(
    st.dictionaries(
        st.sampled_from(["render", "camera", "materials", "lights", "objects", "extra"]), json_value, max_size=5
    )
)
def test_loader_never_crashes_on_arbitrary_documents(doc):
    try:
        raylume.scene_from_dict(doc)
    except SceneError as exc:
        assert str(exc).startswith("<scene>: ")


@settings(max_examples=150, deadline=None)
@given(scene_doc, st.data())
def test_mutated_documents_give_clear_errors(doc, data):
    """Replace one value somewhere in a valid document with junk: a SceneError or a scene."""
    keys = [("render", k) for k in doc["render"]] + [("objects", i) for i in range(len(doc["objects"]))]
    if not keys:
        return
    where = data.draw(st.sampled_from(keys))
    junk = data.draw(st.one_of(st.text(max_size=4), st.floats(), st.lists(st.integers(), max_size=4), st.none()))
    doc = json.loads(json.dumps(doc))
    doc[where[0]][where[1]] = junk
    try:
        raylume.scene_from_dict(doc)
    except SceneError as exc:
        assert str(exc).startswith("<scene>: ")


@pytest.mark.parametrize("mode", ["cast", "trace", "path"])
def test_a_light_past_float32_s_range_gives_no_inf_pixels(mode):
    """A light of 3e38 (within float32's range, so the scene takes it) 0.1 above a white plane
    lights it past that range (I / d^2 = 3e40): the image holds float32's largest value there,
    never inf."""
    glowing = {"type": "diffuse", "color": [0.8, 0.8, 0.8], "emission": [1e38, 1e38, 1e38]}
    scene = raylume.scene_from_dict(
        {
            "render": {"width": 16, "height": 12, "spp": 2, "max_depth": 3},
            "camera": {"position": [0, 0, -3], "look_at": [0, 0, 0]},
            "lights": [{"type": "point", "position": [0, -0.9, -1.2], "intensity": 3e38}],
            "objects": [
                {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": glowing},
                {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0]},
            ],
        }
    )
    image = raylume.render(scene, mode=mode, aovs=False)
    assert np.isfinite(image.rgb).all()
    if mode == "path":  # (cast mode shows colours, unlit; trace mode's pixels miss the spot)
        assert image.rgb.max() == np.finfo(np.float32).max
