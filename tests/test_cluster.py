"""Rendering on a Dask cluster: bit-identical to the in-process render (the reference) in every
mode, whatever the tiles, passes, order of finishing or a worker killed mid-render; Ctrl-C,
mismatched versions and unreachable schedulers. One local cluster of two single-threaded worker
processes serves the module; one test starts `dask scheduler` / `dask worker` processes."""

from __future__ import annotations

import contextlib
import gc
import json
import logging
import os
import random
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import warnings

import numba
import numpy as np
import pytest
from test_cli import raylume
from typer.testing import CliRunner

import raylume as rl
from raylume import cluster as C
from raylume.animation import render_animation
from raylume.cli import app
from raylume.denoise import is_available as denoise_available
from raylume.render_window import RenderInterrupted
from raylume.settings import resolve_settings

distributed = pytest.importorskip("distributed")

# One pytest-xdist worker runs this module (make test: --dist loadgroup): one local cluster of
# two processes, not one per xdist worker, and the kernels loaded by one process.
pytestmark = pytest.mark.xdist_group("cluster")

# The seed scene, small: its kernel variant (spheres only) is the one the rest of the suite
# compiles first, so these tests seldom pay a compilation of their own.
SCENE = {
    "render": {"width": 40, "height": 30},
    "camera": {"position": [0, 0.5, -1], "look_at": [0, 0, 3]},
    "lights": [
        {"type": "ambient", "intensity": 0.2},
        {"type": "point", "position": [2, 1, 0], "intensity": 0.6},
        {"type": "directional", "direction": [1, 4, 4], "intensity": 0.2},
    ],
    "objects": [
        {"type": "sphere", "center": [0, -1, 3], "radius": 1, "material": {"color": [1, 0, 0], "reflective": 0.2}},
        {"type": "sphere", "center": [2, 0, 4], "radius": 1, "material": {"color": [0, 0, 1], "specular": 500}},
        {
            "type": "sphere",
            "center": [0, -5001, 0],
            "radius": 5000,
            "material": {"color": [1, 1, 0], "reflective": 0.5},
        },
    ],
}


# How long the killed-worker tests wait for the nannies' new workers before the next test: on a
# loaded 2-core machine (the other test process busy beside them) one took over 60 s to register.
# A harness wait, not the behaviour under test (the render finishing is).
RESTART_SECONDS = 180


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=40
    )
    client = distributed.Client(cluster, set_as_default=False)
    yield client
    client.close(timeout=10)
    cluster.close(timeout=10)


@pytest.fixture(scope="module")
def session():
    return rl.Session(rl.scene_from_dict(SCENE))


def assert_same(reference, image):
    assert np.array_equal(reference.rgb, image.rgb)
    assert reference.aovs.keys() <= image.aovs.keys()
    for name in reference.aovs:
        assert np.array_equal(reference.aovs[name], image.aovs[name]), name


@pytest.mark.parametrize(
    "mode, spp, pixel_filter",
    [("cast", 3, "box"), ("trace", 4, "mitchell"), ("path", 6, "gaussian"), ("raster", 1, "box")],
)
def test_cluster_render_is_bit_identical_to_the_in_process_render(client, session, mode, spp, pixel_filter):
    settings = dict(mode=mode, spp=spp, filter=pixel_filter, seed=7)
    reference = session.render(threads=2, **settings)
    image = session.render(cluster=client, **settings)
    assert_same(reference, image)
    stats = image.stats["cluster"]
    assert stats["workers"] == 2
    assert stats["tiles"] >= (1 if mode == "raster" else 8)
    assert sum(w["tasks"] for w in stats["per_worker"].values()) == stats["tasks"]
    # render_seconds is the kernels' time, as in-process (DESIGN): summed over the tiles, not the
    # cluster's wall time with its warm-up and scheduling; the rate is the kernels' too
    assert image.stats["render_seconds"] == stats["kernel_seconds"] > 0
    assert stats["kernel_seconds"] == pytest.approx(sum(w["render_seconds"] for w in stats["per_worker"].values()))
    assert stats["wall_seconds"] > 0 and "wall_seconds" not in image.stats
    if mode != "raster":
        assert image.stats["mrays_per_second"] == pytest.approx(image.stats["rays"] / stats["kernel_seconds"] / 1e6)
    # the workers' compile (or load) time: the longest of them, reported where they report it
    compiles = [w["compile_seconds"] for w in stats["per_worker"].values() if "compile_seconds" in w]
    assert compiles and stats["compile_seconds"] == max(compiles) > 0
    assert image.stats["compile_seconds"] >= stats["compile_seconds"]


@pytest.mark.parametrize("width, height", [(40, 30), (23, 40)])
def test_adaptive_sampling_on_a_cluster_is_bit_identical_to_the_in_process_render(client, session, width, height):
    """With a noise threshold the cluster's tiles sample adaptively, their edges on the grid of
    adaptive sampling's tiles, each of which stops as in-process: the same image, spp AOV and
    statistics (stopped by noise where every tile converged, as in-process, though some of the
    cluster's tasks had each of their tiles converge only at its last round), for the whole
    image and for a crop; a time limit is left out with a warning."""
    settings = dict(mode="path", spp=64, noise_threshold=0.05, min_spp=8, seed=5, width=width, height=height)
    reference = session.render(threads=2, **settings)
    image = session.render(cluster=client, **settings)
    assert_same(reference, image)
    assert len(np.unique(image.aovs["spp"])) > 1  # its tiles stopped apart
    assert image.stats["adaptive"] == reference.stats["adaptive"]
    assert image.stats["primary_rays"] == reference.stats["primary_rays"] < width * height * 64
    crop = session.render(cluster=client, crop=(5, 21, 3, 21), **settings)
    assert np.array_equal(crop.rgb, reference.rgb[3:21, 5:21])
    assert np.array_equal(crop.aovs["spp"], reference.aovs["spp"][3:21, 5:21])
    with pytest.warns(rl.SceneWarning, match="time_limit is ignored on a cluster"):
        timed = session.render(cluster=client, time_limit=1e6, **settings)
    assert np.array_equal(timed.rgb, reference.rgb)


def test_adaptive_sampling_on_a_cluster_warns_in_the_caller_and_stops_cleanly(client, session, monkeypatch):
    """The warning that no tile can stop early comes once, in the caller (the workers' tasks are
    quiet); Ctrl-C before any tile is done is a RenderInterrupted, as without a threshold."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        session.render(cluster=client, mode="path", spp=3, noise_threshold=0.05)
    said = [w for w in caught if "every pixel takes them all" in str(w.message)]
    assert len(said) == 1 and issubclass(said[0].category, rl.SceneWarning)
    monkeypatch.setattr(C, "TILE_SECONDS", 1e-9)

    def progress(done, total):
        raise KeyboardInterrupt

    with pytest.raises(RenderInterrupted) as stopped:
        session.render(cluster=client, mode="path", spp=64, noise_threshold=0.05, progress=progress)
    assert "tiles" in stopped.value.done


def test_bdpt_cluster_render_is_bit_identical_to_the_in_process_render(client, session):
    """Bidirectional path tracing on a cluster: every tile is the full render's window (its
    splats come from every pixel's light subpath and are summed exactly), so the pasted tiles
    are the in-process image bit for bit, with a filter whose splats cross tile edges."""
    settings = dict(mode="path", integrator="bdpt", spp=3, filter="gaussian", seed=7)
    assert_same(session.render(threads=2, **settings), session.render(cluster=client, **settings))


def test_bdpt_glints_on_a_cluster_are_bit_identical_to_the_in_process_render(client):
    """bdpt's glint strategy on a cluster: each tile makes the whole image's guide (the same bits
    on any worker) and splats the strategy's samples of every pixel into its window."""
    from test_bdpt_glint import _glint_scene

    glints = rl.Session(_glint_scene(0.05))
    settings = dict(mode="path", integrator="bdpt", spp=3, seed=7)
    local = glints.render(threads=2, **settings)
    assert local.stats["bdpt_strategies"].get("glint", 0) > 0
    assert_same(local, glints.render(cluster=client, **settings))


def test_passes_and_tiles_finishing_in_shuffled_order_give_the_same_bits(client, session, monkeypatch):
    monkeypatch.setattr(C, "TILE_SECONDS", 1e-9)  # every tile as small as allowed, one sample per pass
    window = (4, 36, 2, 26)
    settings = resolve_settings(session.scene, {"mode": "path", "spp": 5, "seed": 3}, crop=window)
    reference = session.render(mode="path", spp=5, seed=3, threads=2, crop=window)
    result = C.render_on_cluster(
        client, session.compiled, session.scene.camera, settings, aovs=True, shuffle=random.Random(5)
    )
    assert np.array_equal(reference.rgb, result.rgb)
    for name in reference.aovs:
        assert np.array_equal(reference.aovs[name], result.aovs[name]), name
    planned = [list(t.window) for t in C.plan_tiles(window, settings.render, 1.0, tile_seconds=1e-9)]
    finished = result.cluster["finish_order"]
    assert sorted(finished) == sorted(planned) and finished != planned
    assert result.cluster["tasks"] == 5 * len(planned)  # chained passes of one sample each


def _assert_killing_workers_mid_render_loses_nothing(client, session, monkeypatch, how_many):
    """Kill the first `how_many` workers (SIGKILL) once the first task is in: the image is the
    in-process render's, bit for bit."""
    monkeypatch.setattr(C, "TILE_SECONDS", 1e-9)
    settings = dict(mode="path", spp=8, seed=11)
    reference = session.render(threads=2, **settings)
    pids = client.run(os.getpid)
    killed = {}

    def progress(done, total):
        if done >= 1 and not killed:
            for _, pid in sorted(pids.items())[:how_many]:
                os.kill(pid, signal.SIGKILL)
            killed.update(done=done, total=total)

    image = session.render(cluster=client, progress=progress, **settings)
    assert killed and killed["done"] < killed["total"] / 2  # killed with most of the work left
    assert_same(reference, image)
    client.wait_for_workers(2, timeout=RESTART_SECONDS)  # the nannies restart them for the tests that follow


def test_a_worker_killed_mid_render_loses_nothing(client, session, monkeypatch):
    _assert_killing_workers_mid_render_loses_nothing(client, session, monkeypatch, 1)


def test_every_worker_killed_mid_render_loses_nothing(client, session, monkeypatch):
    """The scene goes down with the last worker holding it (Dask keeps a single copy of a
    broadcast value once no task waits for it, so one worker's death can be enough): it is
    scattered again to the restarted workers and the unfinished tiles resubmitted."""
    _assert_killing_workers_mid_render_loses_nothing(client, session, monkeypatch, 2)


def test_every_worker_killed_during_the_warm_up_loses_nothing(client, session, monkeypatch):
    """The warm-up tasks are pinned to the workers there were; killed, they come back at new
    addresses (their nannies restart them) and the scene may be gone with them. The render
    warms the new workers (sending the scene again if it was lost) instead of waiting forever
    for the old ones."""
    settings = dict(mode="trace", spp=2)
    reference = session.render(threads=2, **settings)
    pids = client.run(os.getpid)
    warm_up = C.FrameRenderer._warm_up

    def kill_then_warm_up(self, camera):
        for pid in pids.values():
            os.kill(pid, signal.SIGKILL)
        return warm_up(self, camera)

    monkeypatch.setattr(C.FrameRenderer, "_warm_up", kill_then_warm_up)
    done = {}
    worker = threading.Thread(target=lambda: done.update(image=session.render(cluster=client, **settings)), daemon=True)
    worker.start()
    worker.join(timeout=180)
    assert "image" in done, "the render still waits for the warm-up of workers that have left"
    assert_same(reference, done["image"])
    client.wait_for_workers(2, timeout=RESTART_SECONDS)  # both restarted, for the tests that follow


def test_ctrl_c_cancels_the_outstanding_tiles(client, session, monkeypatch):
    monkeypatch.setattr(C, "TILE_SECONDS", 1e-9)

    def progress(done, total):
        if done >= 2:
            raise KeyboardInterrupt

    with pytest.raises(RenderInterrupted) as caught:
        session.render(cluster=client, mode="trace", spp=16, progress=progress)
    assert "tiles" in caught.value.done
    deadline = time.monotonic() + 10
    while any(client.processing().values()) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(client.processing().values())  # nothing left running on the workers


def test_ctrl_c_in_a_terminal_with_local_workers_prints_one_line(tmp_path):
    """Ctrl-C in a terminal signals the whole foreground process group, the local cluster's
    worker processes too: each died printing a KeyboardInterrupt traceback (about 67 lines for
    two) after raylume's own line. They ignore it now; raylume cancels their work and stops them."""
    from test_reliability import _sigint_as_in_a_terminal, _watch

    env = {**os.environ, "TTY_COMPATIBLE": "1", "TTY_INTERACTIVE": "1"}  # Rich draws its bar into the pipe
    command = ["render", "--cluster", "local:2", "--mode", "path", "--spp", "4096", "--width", "128", "--height", "128"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "raylume.cli", *command, "-o", "x.png"],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env=env,
        preexec_fn=_sigint_as_in_a_terminal,
        start_new_session=True,  # a process group of its own, as a terminal's foreground job
    )
    try:
        seen, chunks = _watch(proc.stderr, b"rendering")  # the progress bar: the workers are up
        assert seen.wait(timeout=120), b"".join(chunks).decode(errors="replace")
        time.sleep(0.5)
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    time.sleep(0.5)  # the reader thread's last chunk, and any worker's late output
    err = b"".join(chunks).decode(errors="replace")
    assert proc.returncode == 130, err
    assert err.rstrip().endswith("raylume: interrupted; nothing written"), err
    for noise in ("Traceback", "KeyboardInterrupt", "ERROR", "Process Dask Worker"):
        assert noise not in err, err
    assert not (tmp_path / "x.png").exists()


def test_workers_with_another_numba_are_refused(client, session, monkeypatch):
    real = C.versions()
    monkeypatch.setattr(C, "versions", lambda: {**real, "numba": "0.1.0"})
    with pytest.raises(C.ClusterError, match=r"numba .*0\.1\.0.*bit-identical"):
        session.render(cluster=client, mode="cast")


def test_animation_frames_on_the_cluster_equal_the_stills(client):
    scene = rl.scene_from_dict(
        {
            **SCENE,
            "render": {"width": 24, "height": 16, "mode": "trace"},
            "animation": {"frames": 5, "camera": [{"frame": 0, "position": [0, 1, -1]}, {"frame": 4, "fov": 40}]},
        }
    )
    session = rl.Session(scene)
    local = dict(render_animation(session, range(1, 5)))
    remote = dict(render_animation(session, range(1, 5), cluster=client))
    assert sorted(remote) == [1, 2, 3, 4]
    for k in remote:
        assert np.array_equal(local[k].rgb, remote[k].rgb), k
        # what an animation's --stats sums: a cluster frame's rays as the still's
        assert remote[k].stats["primary_rays"] == local[k].stats["primary_rays"] == 24 * 16
        assert remote[k].stats["rays"] == local[k].stats["rays"] and remote[k].stats["render_seconds"] > 0


def test_an_animations_stats_and_summary_on_the_cluster_say_what_a_stills_say(client, tmp_path, capsys):
    """compile_seconds: the workers' (the longest), as a still on a cluster reports it (it was 0.0);
    the summary names the workers."""
    from raylume.cli import _compile_notice, _progress
    from raylume.cli_animation import render_animation_to
    from raylume.settings import resolve_settings

    scene = rl.scene_from_dict(
        {**SCENE, "render": {"width": 8, "height": 6, "mode": "trace"},
         "animation": {"frames": 2, "camera": [{"frame": 0, "position": [0, 1, -1]}, {"frame": 1, "fov": 40}]}}
    )  # fmt: skip
    render_animation_to(
        scene, "s.toml", tmp_path / "a.gif", None, resolve_settings(scene), cluster=client,
        stats_path=tmp_path / "a.json", progress_bar=_progress, compile_notice=_compile_notice,
    )  # fmt: skip
    stats = json.loads((tmp_path / "a.json").read_text())
    assert stats["compile_seconds"] == stats["cluster"]["compile_seconds"] > 0
    said = capsys.readouterr().err
    assert "2 frames 8x6 trace" in said and "; on 2 workers (" in said, said


def test_an_animation_on_the_cluster_says_the_scenes_warnings(client):
    """In-process frames go through Session.render, which says them; the cluster's did not."""
    scene = rl.scene_from_dict(
        {**SCENE, "lights": [], "render": {"width": 8, "height": 6, "mode": "trace"},
         "animation": {"frames": 2, "camera": [{"frame": 0, "position": [0, 1, -1]}, {"frame": 1, "fov": 40}]}}
    )  # fmt: skip
    with pytest.warns(rl.SceneWarning, match="no lights"):
        assert len(dict(render_animation(rl.Session(scene), cluster=client))) == 2


@pytest.mark.skipif(not denoise_available(), reason="pyoidn (raylume[denoise]) is not installed")
def test_denoised_adaptive_animation_frames_on_the_cluster_equal_the_stills(client):
    """Denoised frames of an adaptive path-traced animation: the cluster's frames are denoised
    on the client as Session.render denoises a still (the light seen directly and the edges at
    the frame's mean spp), so each equals the in-process frame."""
    scene = rl.scene_from_dict(
        {
            **SCENE,
            "render": {"width": 24, "height": 16, "mode": "path", "spp": 32, "denoise": True},
            "animation": {"frames": 3, "camera": [{"frame": 0, "position": [0, 1, -1]}, {"frame": 2, "fov": 40}]},
        }
    )
    session = rl.Session(scene)
    settings = dict(noise_threshold=0.1, min_spp=8)
    local = dict(render_animation(session, range(3), threads=1, **settings))
    before = numba.get_num_threads()
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)  # the machine's cores (2 on CI's)
    remote = dict(render_animation(session, range(3), cluster=client, threads=1, **settings))
    for k in remote:
        assert np.array_equal(local[k].rgb, remote[k].rgb), k
        assert remote[k].stats["adaptive"]["mean_spp"] == local[k].stats["adaptive"]["mean_spp"]
    # the frames' denoising on 1 thread gave Numba back the count it found, as a render does
    assert numba.get_num_threads() == numba.config.NUMBA_NUM_THREADS
    numba.set_num_threads(before)


def test_a_malformed_or_unreachable_address_exits_2_within_10_seconds(tmp_path, monkeypatch):
    """The command in this process (CliRunner), so that the time measured is raylume's, not a
    new interpreter's start on a busy machine."""
    monkeypatch.chdir(tmp_path)
    malformed = CliRunner().invoke(app, ["render", "--cluster", "somewhere"])
    assert malformed.exit_code == 2, malformed.output
    assert "--cluster somewhere" in malformed.output and "tcp://HOST:PORT" in malformed.output
    for port in (0, 99999):  # no port: malformed at once (it waited for the refusal)
        bad = CliRunner().invoke(app, ["render", "--cluster", f"tcp://127.0.0.1:{port}"])
        assert bad.exit_code == 2 and "tcp://HOST:PORT" in bad.output, bad.output
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]  # nothing listens there once closed
    started = time.monotonic()
    result = CliRunner().invoke(
        app, ["render", "--cluster", f"tcp://127.0.0.1:{port}", "--width", "8", "--height", "8"]
    )
    assert time.monotonic() - started < 10
    assert result.exit_code == 2, result.output
    assert f"tcp://127.0.0.1:{port}" in result.output and "dask scheduler" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "render.png").exists()


def _listener(reply: bytes | None):
    """A TCP listener on a free loopback port that is no Dask scheduler: each connection accepted
    and either left silent (reply None, as a server waiting for its client to speak) or sent
    `reply` (an HTTP server's answer) and kept open. Returns (port, stop)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    server.settimeout(0.1)
    accepted, stopped = [], threading.Event()

    def serve():
        while not stopped.is_set():
            try:
                connection = server.accept()[0]
            except OSError:
                continue
            if reply is not None:
                connection.sendall(reply)
            accepted.append(connection)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()

    def stop():
        stopped.set()
        thread.join(timeout=5)
        for connection in accepted:
            connection.close()
        server.close()

    return server.getsockname()[1], stop


@pytest.mark.parametrize(
    "reply, words",
    [(None, "something else is listening there"), (b"HTTP/1.1 400 Bad Request\r\n\r\n" * 4, "not Dask's protocol")],
    ids=["silent", "http"],
)
def test_a_listener_that_is_no_scheduler_exits_2_within_10_seconds(tmp_path, monkeypatch, reply, words):
    """Something else listening at the address: one that accepts and never answers hung the
    Client's handshake forever; one that answers other bytes failed with NumPy's "Unable to allocate
    3.07 EiB" and a half-started Client whose __del__ printed a traceback at exit. The command runs
    on a thread here, so that a hang fails the test instead of hanging it."""
    monkeypatch.chdir(tmp_path)
    unraisable = []
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)
    port, stop = _listener(reply)
    address = f"tcp://127.0.0.1:{port}"
    done = {}
    try:
        started = time.monotonic()
        command = threading.Thread(
            target=lambda: done.update(
                result=CliRunner().invoke(app, ["render", "--cluster", address, "--width", "8"])
            ),
            daemon=True,
        )
        command.start()
        command.join(timeout=15)
        seconds = time.monotonic() - started
    finally:
        stop()
    assert "result" in done, f"raylume render --cluster {address} still waits after 15 s"
    result = done["result"]
    assert seconds < 10 and result.exit_code == 2, (seconds, result.output)
    assert f"--cluster {address}" in result.output and words in result.output, result.output
    assert "Traceback" not in result.output and "allocate" not in result.output
    gc.collect()  # a half-started Client's __del__ would run here
    assert not unraisable, [u.exc_value for u in unraisable]
    assert not (tmp_path / "render.png").exists()


def _start(*args, env=None):
    return subprocess.Popen(
        [sys.executable, "-m", "dask", *map(str, args)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=None if env is None else {**os.environ, **env},
    )


def _stop(process):
    process.terminate()
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(timeout=10)


@contextlib.contextmanager
def _dask_processes(tmp_path, workers=2, worker_env=None):
    """`dask scheduler` and `dask worker` processes on the loopback address, as a user starts
    them: yields (the scheduler's address, its process) once `workers` workers have joined."""
    address_file = tmp_path / "scheduler.json"
    scheduler = _start(
        "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", address_file
    )
    worker = None
    try:
        deadline = time.monotonic() + 60
        while not address_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(address_file.read_text())["address"]
        worker = _start(
            "worker", address, "--nworkers", workers, "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1",
            env=worker_env,
        )  # fmt: skip
        with distributed.Client(address, timeout=30, set_as_default=False) as probe:
            probe.wait_for_workers(workers, timeout=60)  # started, not only launched
        yield address, scheduler
    finally:
        if worker is not None:
            _stop(worker)
        _stop(scheduler)


def test_a_cluster_of_dask_scheduler_and_dask_worker_processes(tmp_path):
    """As a user starts a real cluster: `dask scheduler`, `dask worker ADDRESS`, then
    `raylume render --cluster ADDRESS`; the image equals the in-process render bit for bit."""
    with _dask_processes(tmp_path) as (address, _):
        scene = tmp_path / "scene.json"
        scene.write_text(json.dumps({**SCENE, "render": {"width": 32, "height": 24, "spp": 2}}))
        result = raylume("render", scene, "-o", "c.npy", "--cluster", address, "--stats", "s.json", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        reference = rl.render(rl.load_scene(scene), aovs=False)
        assert np.array_equal(np.load(tmp_path / "c.npy"), reference.rgb)
        stats = json.loads((tmp_path / "s.json").read_text())
        assert stats["cluster"]["workers"] == 2 and stats["cluster"]["per_worker"]


def test_a_worker_without_raylume_is_refused_in_one_line(tmp_path):
    """A worker where raylume cannot be imported (here a package of that name whose import fails,
    first on its PYTHONPATH): the version check's run of raylume's code fails there, which was a
    page of distributed's traceback and exit 1; it is one line naming the worker, and exit 2."""
    fake = tmp_path / "fake" / "raylume"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('No module named raylume')\n")
    with _dask_processes(tmp_path, workers=1, worker_env={"PYTHONPATH": str(fake.parent)}) as (address, _):
        result = raylume("render", "--cluster", address, "--width", "8", "--height", "8", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    [line] = result.stderr.splitlines()
    assert re.fullmatch(
        r"raylume: error: worker tcp://127\.0\.0\.1:\d+ is refused: raylume cannot be imported .*", line
    )
    assert "install the client's raylume" in line
    assert not (tmp_path / "render.png").exists()


def test_a_scheduler_killed_mid_render_is_one_error_naming_it(tmp_path, session, monkeypatch):
    """The scheduler killed (SIGKILL) once the first tile is in: an error naming --cluster ADDRESS
    and the scheduler's loss, not distributed's "Timed out trying to connect", and no log line of
    the client's failed reconnection on stderr."""
    monkeypatch.setattr(C, "TILE_SECONDS", 1e-9)  # many small tasks: most are left when it dies
    logged = []
    handler = logging.Handler(logging.WARNING)
    handler.emit = logged.append
    logging.getLogger("distributed.client").addHandler(handler)
    try:
        with _dask_processes(tmp_path, workers=1) as (address, scheduler):

            def progress(done, total):
                if done >= 1 and scheduler.poll() is None:
                    scheduler.kill()

            with pytest.raises(C.ClusterError) as caught:
                session.render(cluster=address, mode="cast", spp=4, progress=progress)
            time.sleep(0.5)  # time for a reconnection's log line
    finally:
        logging.getLogger("distributed.client").removeHandler(handler)
    message = str(caught.value)
    assert f"--cluster {address}: the scheduler was lost during the render" in message, message
    assert not [r.getMessage() for r in logged if r.levelno >= logging.ERROR]
    assert address not in C._clients  # closed and forgotten: a later render connects afresh


def test_exit_after_a_close_that_timed_out_logs_no_lost_data(tmp_path):
    """A local cluster's scheduler runs in the process: when a client's close times out at exit (a
    loaded machine), it still holds the scattered scene, and its loss must not reach stderr as an
    ERROR after a render that succeeded."""
    _exit_quietly_with_scattered_data(
        tmp_path,
        "    client.close = lambda timeout=None: None  # the close that timed out\n"
        "    cluster._close_all()\n"
        "    print('done', flush=True)\n",
    )


def test_exit_with_scattered_data_logs_no_lost_data(tmp_path):
    """A program (or raylume's command) that ends with its client still holding scattered data
    and no explicit close: distributed's exit handler, registered as distributed was imported,
    ran before raylume's and closed the local cluster first, and its scheduler logged the
    data's loss as an ERROR after a render that succeeded."""
    _exit_quietly_with_scattered_data(tmp_path, "    print('done', flush=True)\n")


def _exit_quietly_with_scattered_data(tmp_path, ending: str) -> None:
    """A program whose client scatters data on a local cluster, then runs `ending` (lines of its
    main block, printing 'done') and exits: it must exit 0 without an ERROR on stderr."""
    script = tmp_path / "exit.py"
    script.write_text(
        "from raylume import cluster\n"
        "if __name__ == '__main__':\n"
        "    client = cluster.connect('local:1')\n"
        "    [scene] = client.scatter([list(range(1000))], broadcast=True)\n" + ending
    )
    result = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert result.returncode == 0 and "done" in result.stdout, result.stderr
    assert "ERROR" not in result.stderr and "lose scattered data" not in result.stderr, result.stderr
