"""The viewer's render thread and Python API in-process (no browser): progressive passes add up
to `Session.render`'s image, a view nobody watches stops, path mode's films are averaged by
their sample counts, `raylume.view` serves and stops."""

from __future__ import annotations

import json
import socket
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

import raylume
from raylume.errors import RaylumeError, SceneError
from raylume.image import encode_8bit
from raylume.kernels.film.film import Film, sums_image
from raylume.settings import resolve_settings
from raylume.viewer import renderer as vr


def seed(**render):
    return raylume.builtin_scene("seed").with_render(width=24, height=18, mode="trace", **render)


def wait_for(predicate, timeout=60.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    raise AssertionError("timed out")


@pytest.mark.parametrize("slow", [False, True])
def test_passes_at_rest_converge_to_session_render_and_stop(slow):
    session = raylume.Session(seed(spp=4))
    r = vr.Renderer(session, resolve_settings(session.scene, threads=1))
    if slow:  # as if a pass took a second: the film is split into row bands, one row each
        r._cost[("trace", False)] = 1.0
    r.add_watcher(1)
    r.start()
    try:
        wait_for(lambda: r.latest is not None and r.latest.converged)
        frames = r.frames
        time.sleep(0.2)
        assert r.frames == frames  # converged: nothing more to render
        assert r.latest.spp == 4 and r.latest.format == "png"
        expected = session.render(width=24, height=18, spp=4, threads=1, aovs=False).to_uint8()
        np.testing.assert_array_equal(r.latest.rgb8, expected)
        assert r.stats()["status"] == "converged"
        if slow:
            assert len(r._job.bands) == 18
    finally:
        assert r.stop(1.0)


def test_the_frames_are_tone_mapped_as_the_render_is():
    session = raylume.Session(seed(spp=4))
    r = vr.Renderer(session, resolve_settings(session.scene, {"tonemap": "agx", "exposure": 1.5}, threads=1))
    r.add_watcher(1)
    r.start()
    try:
        wait_for(lambda: r.latest is not None and r.latest.converged)
        expected = session.render(width=24, height=18, spp=4, threads=1, aovs=False, tonemap="agx", exposure=1.5)
        np.testing.assert_array_equal(r.latest.rgb8, expected.to_uint8())
        assert not np.array_equal(r.latest.rgb8, session.render(width=24, height=18, spp=4, aovs=False).to_uint8())
    finally:
        assert r.stop(1.0)


def test_a_view_nobody_watches_stops_after_one_lossless_frame():
    session = raylume.Session(seed(spp=64))
    r = vr.Renderer(session, resolve_settings(session.scene, threads=1))
    r.start()
    try:
        wait_for(lambda: r.latest is not None)
        time.sleep(0.3)
        frames, spp = r.frames, r.latest.spp
        time.sleep(0.3)
        assert r.frames == frames and spp < 64 and not r.latest.converged
        r.add_watcher(1)  # a tab opens: refining goes on
        wait_for(lambda: r.latest.spp > spp)
    finally:
        r.stop(1.0)


def test_camera_and_mode_changes_are_validated():
    r = vr.Renderer(raylume.Session(seed()))
    assert r.set_camera({"fov": 40}) == 1 and r.camera.fov == 40
    with pytest.raises(SceneError, match="fov"):
        r.set_camera({"fov": 400})
    with pytest.raises(SceneError, match="zoom"):
        r.set_camera({"zoom": 1})
    with pytest.raises(SceneError, match="expected one of"):
        r.set_mode("wireframe")
    assert r.camera_version == 1
    r.gesture("orbit", dx=10, dy=0)
    assert r.camera_version == 2 and r.camera.position != (0.0, 0.0, 0.0)
    r.reset_camera()
    assert r.camera.position == (0.0, 0.0, 0.0) and r.camera.fov == pytest.approx(53.13)


def test_path_films_are_pooled_by_their_sums():
    # two completed films of 16 spp (means 1 and 3) and a third film with 8 spp of mean 6
    job = vr._Job(0, 0, None, "path", 1, None, 16)
    for mean in (1.0, 3.0, 6.0):
        job.bands = [Film(2, 2, "box", total_spp=16, window=(0, 2, y, y + 1)) for y in (0, 1)]
        n = 8 if mean == 6.0 else 16
        for band in job.bands:
            band.sums[..., :3] = mean * n
            band.sums[..., 3] = n
            band.spp = n
        if n == 16:
            job.pool_film()
    np.testing.assert_allclose(job.image(), (16 + 48 + 48) / 40)
    assert job.spp == 40 and job.done_spp == 32


@pytest.mark.parametrize("port", [70000, -1, 8.5, True])
def test_python_api_refuses_a_port_beyond_0_to_65535(port):
    """The socket took 70000 as 4464, and -1 failed as a bad host."""
    with pytest.raises(ValueError, match=r"port=.*: expected 0\.\.65535"):
        raylume.view("seed", width=8, height=6, mode="cast", port=port, show=False)


def test_a_background_view_left_running_ends_with_the_interpreter_quietly(tmp_path):
    """live-view.md: "url.stop() # or leave it: it ends with the interpreter". It ended with a
    traceback (the renderer stopped through an executor already shut down at exit)."""
    import subprocess
    import sys

    code = (
        "import raylume\n"
        "url = raylume.view('seed', width=16, height=12, mode='cast', threads=1, show=False)\n"
        "print(url, flush=True)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.startswith("http://127.0.0.1:"), done.stderr
    assert "Traceback" not in done.stderr and "Error" not in done.stderr, done.stderr


def test_python_api_serves_in_the_background_and_stops():
    url = raylume.view("seed", width=24, height=18, mode="trace", threads=1, show=False)
    try:
        assert url.startswith("http://127.0.0.1:") and "?token=" in url
        base, _, token = url.partition("/?token=")
        png = urllib.request.urlopen(f"{base}/frame.png?token={token}", timeout=60).read()
        from io import BytesIO

        from PIL import Image

        shown = np.asarray(Image.open(BytesIO(png)).convert("RGB"))
        expected = raylume.render(seed(), threads=1, aovs=False)
        np.testing.assert_array_equal(shown, encode_8bit(expected.rgb, "clamp"))
        stats = json.loads(urllib.request.urlopen(f"{base}/stats?token={token}", timeout=10).read())
        assert (stats["width"], stats["height"], stats["mode"]) == (24, 18, "trace")
    finally:
        url.stop()
    port = int(base.rsplit(":", 1)[1])
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", port))


@pytest.mark.parametrize(
    "args, words",
    [
        (["--threads", "0"], ["--threads 0"]),
        (["--port", "70000"], ["--port 70000"]),
        (["--mode", "wireframe"], ["--mode"]),
        (["--set", "camera.fov=500"], ["camera.fov"]),
        (["nosuch.toml"], ["nosuch.toml"]),
        (["--tonemap", "filmic"], ["--tonemap", "agx"]),
    ],
)
def test_bad_view_flags_are_refused_before_serving(args, words):
    from typer.testing import CliRunner

    from raylume.cli import app

    port = [] if "--port" in args else ["--port", "0"]
    result = CliRunner().invoke(app, ["view", *args, *port, "--no-browser"])
    assert result.exit_code == 2, result.output
    assert "raylume view:" not in result.output  # no URL: nothing was served
    for word in words:
        assert word in result.output


CORNELL = Path(__file__).resolve().parents[1] / "examples" / "cornell.toml"


def cornell(**render):
    return raylume.load_scene(CORNELL).with_render(width=24, height=18, mode="path", **render)


def pooled_films(session, films: int, pixel_filter: str, **samples) -> tuple[np.ndarray, np.ndarray | None]:
    """The sums and splat sums (bdpt) of `films` films of 16 spp that follow each other in one
    sequence, added."""
    sums = splats = None
    for k in range(films):
        film = raylume.Film(24, 18, pixel_filter, total_spp=16, first_sample=16 * k)
        session.add_samples(film, 16, threads=1, **samples)
        sums = film.sums.copy() if sums is None else sums + film.sums
        if film.splats is not None:
            splats = film.splats.copy() if splats is None else splats + film.splats
    return sums, splats


@pytest.mark.parametrize("pixel_filter", ["box", "mitchell"])
def test_denoising_leaves_the_accumulation_as_it_is(pixel_filter):
    """With denoise on, path mode's films still hold exactly the films of 16 spp that follow
    each other in one sequence (the bits of films without --denoise), pooled as without
    denoising: only what is shown is denoised. Together they are `raylume render`'s image of
    all their samples (to rounding: the Cornell box has no texture, whose filter a film's own
    total sets), with Mitchell's negative lobes too, whose films' mean image would not be."""
    session = raylume.Session(cornell(spp=16, denoise=True, filter=pixel_filter))
    r = vr.Renderer(session, resolve_settings(session.scene, threads=1))
    r.add_watcher(1)
    r.start()
    try:
        wait_for(lambda: r._job is not None and r._job.done_spp >= 32, timeout=300)
    finally:
        assert r.stop(5.0)
    job = r._job
    np.testing.assert_array_equal(job.done_sums, pooled_films(session, job.done_spp // 16, pixel_filter)[0])
    whole = session.render(spp=job.done_spp, denoise=False, threads=1, aovs=False).rgb
    pooled = sums_image(job.done_sums, None, job.done_spp)
    np.testing.assert_allclose(pooled, whole, rtol=1e-5, atol=1e-6)
    assert r.latest.denoised and r.stats()["denoise"] is True and r.stats()["integrator"] == "path"


def test_the_resting_image_is_shown_denoised_or_not_as_asked():
    """Nobody watching: the thread stops after the first resting frame, so the job's image is
    fixed. Switching denoising shows it again at once: OIDN's output of it, or it as it is."""
    from raylume.denoise import denoise

    session = raylume.Session(cornell(spp=16, denoise=True))
    r = vr.Renderer(session, resolve_settings(session.scene, threads=1))
    r.start()
    try:
        wait_for(lambda: r.latest is not None and r.stats()["status"] == "paused (no viewer)", timeout=300)
        job, frames = r._job, r.frames
        image, settings = job.image(), job.settings
        assert r.latest.denoised and r.latest.format == "png"
        albedo, normal = job.aovs["albedo"], job.aovs["normal"]
        np.testing.assert_array_equal(r.latest.rgb8, encode_8bit(denoise(image, albedo, normal), settings.encoding))
        r.set_denoise(False)
        wait_for(lambda: r.frames == frames + 1)
        assert not r.latest.denoised and r.stats()["denoise"] is False
        np.testing.assert_array_equal(r.latest.rgb8, encode_8bit(image, settings.encoding))
        r.set_denoise(True)
        wait_for(lambda: r.frames == frames + 2)
        assert r.latest.denoised and r.latest.spp == job.spp
        np.testing.assert_array_equal(r.latest.rgb8, encode_8bit(denoise(image, albedo, normal), settings.encoding))
    finally:
        assert r.stop(5.0)


def test_a_converged_resting_image_is_shown_as_it_is(monkeypatch):
    """From DENOISE_UNTIL_SPP samples a pixel on, the resting image is the accumulation itself
    (what converges to `raylume render`), no longer OIDN's output of it."""
    monkeypatch.setattr(vr, "DENOISE_UNTIL_SPP", 32)
    session = raylume.Session(cornell(spp=16, denoise=True))
    r = vr.Renderer(session, resolve_settings(session.scene, threads=1))
    r.add_watcher(1)
    shown = []
    r.on_frame = lambda f: shown.append((f.spp, f.denoised))
    r.start()
    try:
        wait_for(lambda: r._job is not None and r._job.done_spp >= 48, timeout=300)
    finally:
        assert r.stop(5.0)
    assert any(d for spp, d in shown if spp < 32)  # denoised while noisy
    assert all(not d for spp, d in shown if spp >= 32)  # then as it is
    assert r.stats()["denoise"] is True and not r.latest.denoised


def test_moving_frames_are_filtered_and_a_move_drops_the_frame_in_progress():
    session = raylume.Session(cornell(spp=16, denoise=True))
    r = vr.Renderer(session, resolve_settings(session.scene, threads=1))
    frames = []
    r.on_frame = frames.append
    r.add_watcher(1)
    r.start()
    try:
        wait_for(lambda: r.latest is not None, timeout=300)
        end = time.monotonic() + 120  # the filter's first compile comes first
        while not any(f.format == "jpeg" and f.denoised for f in frames) and time.monotonic() < end:
            r.gesture("orbit", dx=2, dy=0)
            time.sleep(0.02)
        version = r.camera_version
        wait_for(lambda: frames[-1].format == "png" and frames[-1].camera_version == version)
    finally:
        assert r.stop(5.0)
    moving = [f for f in frames if f.format == "jpeg"]
    assert moving and all(f.denoised and f.spp == 1 and not f.converged for f in moving)
    assert all(np.isfinite(f.rgb8).all() for f in moving)
    # every frame sent shows a camera no older than the one before it: none waited behind a move
    versions = [f.camera_version for f in frames]
    assert versions == sorted(versions)
    assert frames[-1].denoised  # at rest: OIDN


def test_denoise_cannot_be_switched_on_without_oidn(monkeypatch):
    import raylume.denoise

    def missing():
        raise RaylumeError("Denoising needs the optional package pyoidn")

    monkeypatch.setattr(raylume.denoise, "_pyoidn", missing)
    r = vr.Renderer(raylume.Session(cornell()))
    with pytest.raises(RaylumeError, match="pyoidn"):
        r.set_denoise(True)
    assert r.stats()["denoise"] is False
    from typer.testing import CliRunner

    from raylume.cli import app

    result = CliRunner().invoke(app, ["view", str(CORNELL), "--denoise", "--port", "0", "--no-browser"])
    assert result.exit_code == 2 and "pyoidn" in result.output
    assert "raylume view:" not in result.output


def test_python_api_takes_a_tonemap():
    """As `raylume view --tonemap`: the frames are the render tone mapped."""
    url = raylume.view("seed", width=24, height=18, mode="trace", tonemap="reinhard", threads=1, show=False)
    try:
        base, _, token = url.partition("/?token=")
        png = urllib.request.urlopen(f"{base}/frame.png?token={token}", timeout=60).read()
        from io import BytesIO

        from PIL import Image

        shown = np.asarray(Image.open(BytesIO(png)).convert("RGB"))
        expected = raylume.render(seed(), threads=1, aovs=False)
        np.testing.assert_array_equal(shown, encode_8bit(expected.rgb, "clamp", 0.0, "reinhard"))
        assert not np.array_equal(shown, encode_8bit(expected.rgb, "clamp"))
    finally:
        url.stop()


def test_python_api_takes_denoise():
    url = raylume.view(cornell(), denoise=True, threads=1, show=False)
    try:
        base, _, token = url.partition("/?token=")
        stats = json.loads(urllib.request.urlopen(f"{base}/stats?token={token}", timeout=10).read())
        assert (stats["mode"], stats["denoise"], stats["integrator"]) == ("path", True, "path")
    finally:
        url.stop()


def test_bdpt_films_are_one_band_and_equal_its_renders():
    """`raylume view --integrator bdpt`: a resting film is one band, however slow a pass (every
    band would trace the whole image's light subpaths), and its films pooled are `raylume
    render`'s bdpt image of all their samples (splats included); /stats says the integrator."""
    session = raylume.Session(cornell(spp=16, integrator="bdpt"))
    r = vr.Renderer(session, resolve_settings(session.scene, threads=1))
    r._cost[("path", False)] = 1.0  # as if a pass took a second: path mode would make row bands
    r.add_watcher(1)
    r.start()
    try:
        wait_for(lambda: r._job is not None and r._job.done_spp >= 32, timeout=300)
    finally:
        assert r.stop(5.0)
    job = r._job
    assert len(job.bands) == 1 and r.stats()["integrator"] == "bdpt"
    sums, splats = pooled_films(session, job.done_spp // 16, "box", integrator="bdpt")
    np.testing.assert_array_equal(job.done_sums, sums)
    np.testing.assert_array_equal(job.done_splats, splats)
    # the pooled films are bdpt's render of all their samples, splats included (to rounding)
    whole = session.render(spp=job.done_spp, threads=1, aovs=False).rgb
    np.testing.assert_allclose(sums_image(sums, splats, job.done_spp), whole, rtol=1e-5, atol=1e-6)


@pytest.fixture
def default_recursion_limit():
    """Python's default recursion limit, which `raylume view` serves under (a test worker's may
    be raised, and the deep messages below would then parse)."""
    import sys

    old = sys.getrecursionlimit()
    sys.setrecursionlimit(1000)
    yield
    sys.setrecursionlimit(old)


def test_bad_messages_get_clear_answers_and_the_view_keeps_serving(default_recursion_limit):
    """A camera body or a page message that is malformed, nested too deeply, of the wrong type
    or too large to compute with gets an answer naming what is wrong (400, or an {"error"}
    message), not a traceback and a dropped connection; the server serves on."""
    import asyncio
    import urllib.error

    from tornado.httpclient import HTTPRequest
    from tornado.websocket import websocket_connect

    url = raylume.view("seed", width=24, height=18, mode="cast", threads=1, show=False)
    try:
        base, _, token = url.partition("/?token=")
        deep = b'{"fov": ' + b"[" * 2000 + b"]" * 2000 + b"}"
        request = urllib.request.Request(f"{base}/camera?token={token}", data=deep, method="POST")
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(request, timeout=30)
        assert refused.value.code == 400 and b"nested too deeply" in refused.value.read()

        messages = {
            json.dumps({"type": "dolly", "delta": 1e7}): "dolly: 'delta' must be a number from -1e+06 to 1e+06",
            '{"type": "orbit", "dx": 1' + "0" * 400 + ', "dy": 0}': "orbit: 'dx' must be a number",
            json.dumps({"type": "pan", "dx": 0, "dy": [[[1]]]}): "pan: 'dy' must be a number",
            json.dumps({"type": "orbit"}): "orbit: 'dx' must be a number from -1e+06 to 1e+06, got null",
            json.dumps({"type": "orbit", "dx": 1, "dy": None}): "orbit: 'dy' must be a number",
            json.dumps([]): "a message is a JSON object with a 'type'",
            json.dumps({"type": "mode"}): "mode: 'mode' must be a mode's name, got null",
            json.dumps({"type": "denoise", "on": 1}): "denoise: 'on' must be true or false, got 1",
            '{"type": ' + "[" * 2000 + "]" * 2000 + "}": "nested too deeply",
            json.dumps({"type": "dolly", "delta": 1e6}): "camera",  # pushed past float32's range: refused
        }

        async def talk():
            ws = base.replace("http://", "ws://") + f"/ws?token={token}"
            conn = await websocket_connect(HTTPRequest(ws, headers={"Origin": base}, connect_timeout=10))
            answers = []
            for message in messages:
                await conn.write_message(message)
                while isinstance(answer := await asyncio.wait_for(conn.read_message(), 30), bytes):
                    pass  # frames
                answers.append(json.loads(answer)["error"])
            conn.close()
            return answers

        for (message, words), answer in zip(messages.items(), asyncio.run(talk()), strict=True):
            assert words in answer, (message[:60], answer)
        body = json.dumps({"fov": 40}).encode()
        moved = json.loads(
            urllib.request.urlopen(urllib.request.Request(f"{base}/camera?token={token}", body), timeout=30).read()
        )
        assert moved["camera"]["fov"] == 40
    finally:
        url.stop()
