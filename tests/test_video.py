"""Videos that cannot be written: ffmpeg failing (a full disk), Pillow or numpy failing, an
interrupted animation. The answer is one line naming the output, exit status 2, and any
existing file left as it was, with no temporary file behind."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from raylume.cli import app
from raylume.errors import OutputError
from raylume.video import VideoWriter

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
