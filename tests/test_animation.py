"""Camera animation: keyframe interpolation against hand-computed cameras, the [animation]
table's validation, and the command line's videos and image sequences (decoded back with
imageio-ffmpeg: frame count, size, fps, and PSNR against the stills of `--frame K`)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image as PILImage
from typer.testing import CliRunner

import raylume as rl
from raylume.animation import camera_at, interpolate, parse_frames
from raylume.cli import app
from raylume.errors import SceneError


@pytest.fixture
def raylume(tmp_path, monkeypatch):
    """The command, run in this process in tmp_path (the kernels load once for every call)."""
    monkeypatch.chdir(tmp_path)
    return lambda *args: CliRunner().invoke(app, [str(a) for a in args])


def assert_refused(result, *words):
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    for word in words:
        assert word in result.output, (word, result.output)


BASE = {
    "render": {"width": 32, "height": 24, "mode": "trace"},
    "camera": {"position": [0, 0, 0], "look_at": [0, 0, 1], "up": [0, 1, 0], "fov": 50},
    "lights": [{"type": "point", "position": [2, 2, 0], "intensity": 0.8}, {"type": "ambient", "intensity": 0.2}],
    "objects": [
        {"type": "sphere", "center": [0, -1, 3], "radius": 1, "material": {"color": [1, 0, 0], "specular": 50}},
        {"type": "sphere", "center": [-2, 0, 4], "radius": 1, "material": {"color": [0, 1, 0]}},
    ],
}


def animated(**animation):
    return rl.scene_from_dict({**BASE, "animation": animation})


def test_linear_keyframes_give_the_hand_computed_cameras():
    scene = animated(
        frames=21,
        interpolation="linear",
        camera=[
            {"frame": 20, "position": [10, 4, -2]},  # out of order on purpose
            {"frame": 0, "position": [0, 0, -2], "fov": 40},
            {"frame": 10, "look_at": [1, 0, 5]},
        ],
    )
    # position: (0,0,-2) at 0 -> (10,4,-2) at 20; frame 5 is a quarter of the way
    assert camera_at(scene, 5).position == pytest.approx((2.5, 1.0, -2.0))
    assert camera_at(scene, 20).position == pytest.approx((10, 4, -2))
    # look_at has one keyframe: held over every frame; fov too; up comes from [camera]
    for k in (0, 7, 20):
        cam = camera_at(scene, k)
        assert cam.look_at == pytest.approx((1, 0, 5))
        assert cam.fov == pytest.approx(40)
        assert cam.up == pytest.approx((0, 1, 0))


def test_catmull_rom_passes_through_the_keyframes_with_the_neighbours_slope():
    keys = [(0, (0.0, 0.0, -4.0)), (10, (4.0, 1.0, -3.0)), (20, (6.0, 3.0, 0.0)), (30, (5.0, 2.0, 4.0))]
    scene = animated(frames=31, camera=[{"frame": f, "position": list(p)} for f, p in keys])
    p0, p1, p2, p3 = (np.array(p) for _, p in keys)
    for f, p in keys:
        assert camera_at(scene, f).position == pytest.approx(tuple(p))
    # the middle of a uniform Catmull-Rom segment: (-p0 + 9 p1 + 9 p2 - p3) / 16
    assert camera_at(scene, 15).position == pytest.approx(tuple((-p0 + 9 * p1 + 9 * p2 - p3) / 16))
    # first segment, one-sided tangent at the start: Hermite with m0 = (p1-p0)/10, m1 = (p2-p0)/20
    s, h = 0.3, 10
    m0, m1 = (p1 - p0) / 10, (p2 - p0) / 20
    expected = (
        (2 * s**3 - 3 * s**2 + 1) * p0
        + (s**3 - 2 * s**2 + s) * h * m0
        + (-2 * s**3 + 3 * s**2) * p1
        + (s**3 - s**2) * h * m1
    )
    assert camera_at(scene, 3).position == pytest.approx(tuple(expected))
    # a scalar track (fov) too, and holding before the first and after the last keyframe
    assert interpolate([(2, 30.0), (4, 50.0)], 3, "catmull-rom") == pytest.approx(40.0)
    assert interpolate([(2, 30.0), (4, 50.0)], 0, "linear") == 30.0
    assert interpolate([(2, 30.0), (4, 50.0)], 9, "linear") == 50.0


@pytest.mark.parametrize(
    "animation, words",
    [
        ({"frames": 4, "camera": [{"frame": 4, "fov": 30}]}, ["animation", "camera[0].frame", "last frame, 3"]),
        ({"frames": 4, "camera": [{"frame": 1}, {"frame": 1}]}, ["camera[1].frame", "keyframe already"]),
        ({"frames": 4, "interpolation": "cubic"}, ["animation.interpolation"]),
        ({"frames": 0}, ["animation.frames"]),
        ({"frames": 4, "camera": [{"frame": 1, "zoom": 2}]}, ["animation.camera[0].zoom", "unknown key"]),
    ],
)
def test_bad_animation_tables_name_the_key(animation, words):
    with pytest.raises(SceneError) as caught:
        rl.scene_from_dict({**BASE, "animation": animation})
    for word in words:
        assert word in str(caught.value)


def test_an_interpolated_camera_that_is_invalid_names_the_frame():
    scene = animated(frames=3, interpolation="linear", camera=[{"frame": 0, "position": [0, 0, 0]},
                                                                {"frame": 2, "position": [0, 0, 2]}])  # fmt: skip
    with pytest.raises(SceneError, match="frame 1.*look_at must differ"):
        camera_at(scene, 1)  # passes through look_at (0, 0, 1)


def test_parse_frames():
    assert parse_frames("2:5", 10) == range(2, 5)
    assert parse_frames(":3", 10) == range(0, 3)
    assert parse_frames("7:", 10) == range(7, 10)
    for bad in ("5:5", "0:11", "x:3", "4"):
        with pytest.raises(SceneError, match="--frames"):
            parse_frames(bad, 10)


FLIGHT = """
[render]
width = 48
height = 32
mode = "trace"
[animation]
frames = 6
fps = 12
[[animation.camera]]
frame = 0
position = [0, 0.5, -1]
look_at = [0, -0.5, 3]
[[animation.camera]]
frame = 5
position = [2, 1.5, 0]
[[lights]]
type = "point"
position = [2, 2, 0]
intensity = 0.8
[[lights]]
type = "ambient"
intensity = 0.2
[[objects]]
type = "sphere"
center = [0, -1, 3]
radius = 1
material = { color = [1, 0.2, 0.1], specular = 50 }
[[objects]]
type = "sphere"
center = [-1.5, 0, 4]
radius = 1
material = { color = [0.2, 0.9, 0.3] }
"""


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def test_video_and_sequence_frames_match_the_stills(tmp_path, raylume):
    import imageio_ffmpeg

    (tmp_path / "flight.toml").write_text(FLIGHT)
    result = raylume("render", "flight.toml", "-o", "flight.mp4", "--quiet")
    assert result.exit_code == 0, result.output
    result = raylume("render", "flight.toml", "-o", "f_%04d.png", "--frames", "3:6", "--quiet")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.glob("f_*.png")) == ["f_0003.png", "f_0004.png", "f_0005.png"]
    # stills rendered in this process, the way --frame K renders them
    scene = rl.load_scene(tmp_path / "flight.toml")
    stills = [rl.render(scene.replace(camera=camera_at(scene, k)), aovs=False).to_uint8() for k in range(6)]
    for k in (3, 4, 5):
        assert np.array_equal(np.asarray(PILImage.open(tmp_path / f"f_{k:04d}.png")), stills[k])

    reader = imageio_ffmpeg.read_frames(str(tmp_path / "flight.mp4"))
    meta = next(reader)
    decoded = [np.frombuffer(frame, np.uint8).reshape(32, 48, 3) for frame in reader]
    assert meta["size"] == (48, 32) and meta["fps"] == pytest.approx(12)
    assert len(decoded) == 6
    values = [psnr(d, s) for d, s in zip(decoded, stills)]
    # H.264 at CRF 18 in yuv420p measured 31-32.5 dB on these tiny frames: most of the error is the
    # colour at half resolution along the spheres' sharp red/green edges
    assert min(values) > 27, values
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_an_animation_shows_the_compile_notice_and_counts_compile_seconds(tmp_path, raylume, monkeypatch):
    """The first frame compiles the mode's kernels (or loads them): an animation showed no
    "compiling the cast-mode kernels..." notice, which a still shows, and its --stats said
    compile_seconds 0.0. The notice here hears the frames' statuses, and each "compiling"
    takes 0.05 s, as a (very quick) compilation would."""
    import json
    import time

    heard = []

    class Notice:
        def __init__(self, quiet, console=None, mode="trace"):
            self.mode = mode

        def __enter__(self):
            return self.status

        def status(self, what):
            heard.append((self.mode, what))
            if what == "compiling":
                time.sleep(0.05)

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr("raylume.cli._compile_notice", Notice)
    (tmp_path / "flight.toml").write_text(FLIGHT)
    args = ("--mode", "cast", "--frames", "0:2", "--stats", "an.json", "--quiet")
    result = raylume("render", "flight.toml", "-o", "a_%04d.png", *args)
    assert result.exit_code == 0, result.output
    assert heard.count(("cast", "compiling")) == 2 and heard.count(("cast", "rendering")) == 2, heard
    assert json.loads((tmp_path / "an.json").read_text())["compile_seconds"] >= 0.1


def test_render_animation_takes_a_scene_as_render_does(tmp_path):
    """A Scene instead of a Session (an AttributeError before): a session of its own."""
    from raylume.animation import render_animation

    (tmp_path / "flight.toml").write_text(FLIGHT)
    scene = rl.load_scene(tmp_path / "flight.toml")
    ((k, image),) = render_animation(scene, [2], width=16, height=12)
    ((_, again),) = render_animation(rl.Session(scene), [2], width=16, height=12)
    assert k == 2 and np.array_equal(image.rgb, again.rgb)


def test_an_animations_stats_hold_the_stats_contract_summed_over_its_frames(tmp_path, raylume):
    """DESIGN.md's --stats keys, as a still's: an animation's lacked threads, rays, primary_rays,
    render_seconds and mrays_per_second. Its rays are its frames' (each a still's)."""
    import json

    (tmp_path / "flight.toml").write_text(FLIGHT)
    result = raylume("render", "flight.toml", "-o", "a_%04d.png", "--frames", "0:3", "--stats", "an.json", "--quiet")
    assert result.exit_code == 0, result.output
    stats = json.loads((tmp_path / "an.json").read_text())
    contract = "width height spp mode threads primitives triangles rays primary_rays build_seconds render_seconds"
    for key in (*contract.split(), "mrays_per_second", "bvh_nodes", "bvh_bytes"):
        assert key in stats, key
    scene = rl.load_scene(tmp_path / "flight.toml")
    stills = [rl.render(scene.replace(camera=camera_at(scene, k)), aovs=False).stats for k in range(3)]
    assert stats["frames"] == 3 and stats["threads"] == stills[0]["threads"] >= 1
    assert stats["primary_rays"] == 3 * 48 * 32 == sum(s["primary_rays"] for s in stills)
    assert stats["rays"] == sum(s["rays"] for s in stills) > stats["primary_rays"]
    assert stats["mrays_per_second"] == pytest.approx(stats["rays"] / stats["render_seconds"] / 1e6)


def test_frame_k_still_and_refusals(tmp_path, raylume):
    (tmp_path / "flight.toml").write_text(FLIGHT)
    (tmp_path / "still.toml").write_text(
        FLIGHT.split("[animation]")[0] + "[[lights]]" + FLIGHT.split("[[lights]]", 1)[1]
    )
    result = raylume("render", "flight.toml", "-o", "k.png", "--frame", 2, "--quiet")
    assert result.exit_code == 0, result.output
    scene = rl.load_scene(tmp_path / "flight.toml")
    still = rl.render(scene.replace(camera=camera_at(scene, 2)), aovs=False).to_uint8()
    assert np.array_equal(np.asarray(PILImage.open(tmp_path / "k.png")), still)
    assert_refused(
        raylume("render", "flight.toml", "-o", "v.mp4", "--width", 33),
        "even width",
    )
    assert_refused(
        raylume("render", "flight.toml", "-o", "k.png", "--frames", "1:3"),
        "--frames",
    )
    assert_refused(raylume("render", "flight.toml", "-o", "k.png", "--frame", 6), "frame 6")
    assert_refused(raylume("render", "still.toml", "-o", "v.mp4"), "[animation]")
    assert not (tmp_path / "v.mp4").exists()
    # 16 bits a channel: PNG frames only, refused before any frame (a video had been 8-bit silently)
    for out in ("v.mp4", "v.gif", "f_%02d.jpg"):
        assert_refused(raylume("render", "flight.toml", "-o", out, "--bit-depth", 16), "--bit-depth 16 is for .png")
    assert not list(tmp_path.glob("f_*")) and not (tmp_path / "v.gif").exists()


def test_a_gif_holds_a_long_still_for_its_longest_delay(tmp_path):
    """A GIF's delay is 16 bits of 1/100 s (655.35 s), and Pillow merges a run of identical frames
    into one, adding their delays: 700 identical frames at 1 fps (and one frame at 0.001 fps)
    had failed with Pillow's OverflowError after every frame was rendered. They are written, the
    run shortened to 655.35 s with a warning; frames that differ keep their delay."""
    from raylume.video import VideoWriter

    red, blue = (np.zeros((8, 8, 3), np.uint8) + np.uint8(c) for c in ((200, 0, 0), (0, 0, 200)))
    path = tmp_path / "still.gif"
    writer = VideoWriter(path, 8, 8, fps=1.0)
    for frame in [blue] + [red] * 700 + [blue]:
        writer.write(frame)
    with pytest.warns(rl.SceneWarning, match=r"frames 1\.\.700 \(the same image\) would show for 700 s"):
        writer.close()
    with PILImage.open(path) as gif:
        delays = []
        for k in range(gif.n_frames):
            gif.seek(k)
            delays.append(gif.info["duration"])
    assert delays[0] == 1000 and delays[-1] == 1000 and 650000 <= delays[1] <= 655350 and len(delays) == 3
    assert (path.stat().st_mode & 0o777) == 0o644 & ~_umask()

    slow = VideoWriter(tmp_path / "slow.gif", 8, 8, fps=0.001)
    slow.write(red)
    with pytest.warns(rl.SceneWarning, match="frame 0 would show for 1000 s"):
        slow.close()


def test_a_partial_video_is_readable_as_a_finished_one(tmp_path):
    """--partial keeps the frames written so far under OUT.partial.EXT, with a finished
    video's permissions (mkstemp's 0600 had stayed)."""
    from raylume.video import VideoWriter

    writer = VideoWriter(tmp_path / "v.gif", 8, 8, fps=10.0)
    writer.write(np.zeros((8, 8, 3), np.uint8))
    kept = writer.abort(keep_as=tmp_path / "v.partial.gif")
    assert kept.exists() and (kept.stat().st_mode & 0o777) == 0o644 & ~_umask()


def _umask() -> int:
    import os

    mask = os.umask(0)
    os.umask(mask)
    return mask
