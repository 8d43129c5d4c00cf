"""Videos that cannot be written: ffmpeg failing (a full disk), Pillow or numpy failing, an
interrupted animation. The answer is one line naming the output, exit status 2, and any
existing file left as it was, with no temporary file behind."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_reliability import _watch
from typer.testing import CliRunner

import raylume
from raylume.cli import app
from raylume.errors import OutputError
from raylume.image import save_array
from raylume.scene.checks import SceneWarning
from raylume.video import VideoWriter

SRC = Path(raylume.__file__).resolve().parents[1]
FLIGHT = Path(__file__).resolve().parents[1] / "examples" / "flight.toml"
SMALL = ("--width", "32", "--height", "24", "--frames", "0:2", "--quiet")
OLD = b"a good video from before"


@pytest.fixture
def raylume(tmp_path, monkeypatch):
    """The command, run in this process in tmp_path (the kernels load once for every call)."""
    monkeypatch.chdir(tmp_path)
    return lambda *args: CliRunner().invoke(app, [str(a) for a in args])


def fake_ffmpeg(folder: Path, monkeypatch, script: str) -> None:
    """An `ffmpeg` that runs `script` (sh), used through IMAGEIO_FFMPEG_EXE as imageio-ffmpeg's is."""
    exe = folder / "fake-ffmpeg"
    exe.write_text("#!/bin/sh\n" + script)
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", str(exe))


def hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_ffmpeg_failing_at_the_end_keeps_the_old_video(tmp_path, raylume, monkeypatch):
    """ffmpeg on a full disk reads every frame, then fails to write the file's end ("Error
    writing trailer") and exits 1: that was a success, and the broken file replaced the old one."""
    bin_folder = tmp_path / "bin"
    bin_folder.mkdir()
    fake_ffmpeg(
        bin_folder,
        monkeypatch,
        'for out; do :; done\ncat > /dev/null\nprintf broken > "$out"\n'
        'echo "[out#0/mp4 @ 0x5581] Error writing trailer: No space left on device" >&2\nexit 1\n',
    )
    (tmp_path / "f.mp4").write_bytes(OLD)
    result = raylume("render", FLIGHT, "-o", "f.mp4", *SMALL)
    assert result.exit_code == 2, result.output
    assert "raylume: error: f.mp4: cannot write the file (No space left on device)" in result.output
    assert "Traceback" not in result.output
    assert (tmp_path / "f.mp4").read_bytes() == OLD
    assert hidden(tmp_path) == []


def test_ffmpeg_stopping_at_once_is_an_output_error(tmp_path, monkeypatch):
    """An ffmpeg that quits before reading (its pipe broken while frames are written) is named
    by its own last words."""
    fake_ffmpeg(tmp_path, monkeypatch, 'echo "[libx264 @ 0x1] Unknown encoder" >&2\nexit 1\n')
    writer = VideoWriter(tmp_path / "v.mp4", 256, 256, fps=10.0)
    with pytest.raises(OutputError, match=r"v\.mp4: cannot write the file \(ffmpeg: Unknown encoder\)"):
        for _ in range(8):  # more than a pipe's buffer
            writer.write(np.zeros((256, 256, 3), np.uint8))
        writer.close()
    writer.abort()
    assert os.listdir(tmp_path) == ["fake-ffmpeg"]


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full, where every write fails: disk full")
def test_a_gif_on_a_full_disk_names_the_file(tmp_path, monkeypatch):
    """Pillow's OSError (ENOSPC, no file name) had been printed as a bare "No space left on
    device". Pillow writes here into /dev/full, as on a full disk."""
    from PIL import Image as PILImage

    real_save = PILImage.Image.save

    def save_on_full_disk(self, fp, *args, **kwargs):
        with open("/dev/full", "wb") as full:
            real_save(self, full, *args, **kwargs)

    monkeypatch.setattr(PILImage.Image, "save", save_on_full_disk)
    (tmp_path / "f.gif").write_bytes(OLD)
    writer = VideoWriter(tmp_path / "f.gif", 8, 8, fps=10.0)
    writer.write(np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(OutputError) as info:
        writer.close()
    assert str(info.value) == f"{tmp_path / 'f.gif'}: cannot write the file (No space left on device)"
    assert (tmp_path / "f.gif").read_bytes() == OLD
    assert hidden(tmp_path) == []


def _running_in(folder: Path) -> list[str]:
    """Command lines of the processes still running that name `folder` (an ffmpeg left behind)."""
    found = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            text = cmdline.read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if str(folder) in text:
            found.append(text)
    return found


@pytest.mark.parametrize(
    ("suffix", "sig"), [(".mp4", signal.SIGTERM), (".gif", signal.SIGTERM), (".mp4", signal.SIGINT)]
)
def test_sigterm_while_frames_are_written_cleans_up_as_ctrl_c(tmp_path, suffix, sig):
    """SIGTERM (kill, a job scheduler) had ended Python at once: a hidden temporary video was
    left (mode 0600), ffmpeg with it, and no word said. It now stops the animation as Ctrl-C
    does, with exit status 128 + 15. Sent once the progress bar shows, so frames are in. Ctrl-C
    (SIGINT) says one line too: a second, "interrupted; nothing written", had followed it."""
    env = {**os.environ, "TTY_COMPATIBLE": "1", "TTY_INTERACTIVE": "1"}  # Rich draws its bar into the pipe
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), env.get("PYTHONPATH", "")])  # this raylume, from any folder
    command = [sys.executable, "-m", "raylume.cli", "render", str(FLIGHT), "-o", f"f{suffix}"]
    proc = subprocess.Popen(
        [*command, "--width", "640", "--height", "480", "--spp", "16"],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env=env,
    )
    seen, chunks = _watch(proc.stderr, b"rendering")
    try:
        assert seen.wait(timeout=120), b"".join(chunks).decode(errors="replace")
        assert proc.poll() is None, "the animation ended before SIGTERM"
        proc.send_signal(sig)
        proc.wait(timeout=30)
    finally:
        proc.kill()
    proc.stderr.close()
    err = b"".join(chunks).decode(errors="replace")
    assert proc.returncode == 128 + sig, err
    assert "raylume: interrupted after" in err and "no video written" in err and "Traceback" not in err
    assert err.count("raylume: interrupted") == 1, err
    assert list(tmp_path.iterdir()) == []
    assert _running_in(tmp_path) == []


def test_a_file_name_of_up_to_255_bytes_is_written(tmp_path):
    """The temporary beside it (a hidden name of the output's and a random part) had gone past
    the file system's 255 bytes for names from ~241 on: the render done, then "File name too long"."""
    frame = np.zeros((8, 8, 3), np.uint8)
    save_array(tmp_path / ("d" * 251 + ".png"), frame.astype(np.float32))
    writer = VideoWriter(tmp_path / ("e" * 251 + ".gif"), 8, 8, fps=10.0)
    writer.write(frame)
    writer.close()
    assert sorted(len(p.name) for p in tmp_path.iterdir()) == [255, 255]


def test_a_gif_faster_than_50_fps_is_warned_about(tmp_path):
    """Most browsers show a GIF frame of under 20 ms for 100 ms: a 1000-fps flight played at 10."""
    with pytest.warns(SceneWarning, match="a GIF at 120 fps: .* plays slower; write an .mp4"):
        writer = VideoWriter(tmp_path / "fast.gif", 8, 8, fps=120.0)
    writer.abort()
