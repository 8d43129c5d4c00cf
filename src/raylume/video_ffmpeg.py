"""ffmpeg as a child process that encodes raw RGB frames into an H.264 .mp4 (the ffmpeg that
the imageio-ffmpeg wheel carries, or IMAGEIO_FFMPEG_EXE).

Run here rather than through imageio_ffmpeg.write_frames, which hides the process: its exit
status was never seen, so a video that ffmpeg failed to finish (a full disk: "Error writing
trailer") was renamed into place as if it were complete. Here a failed ffmpeg is an
OutputError that gives ffmpeg's reason in words."""

from __future__ import annotations

import errno
import os
import re
import subprocess
import tempfile
from fractions import Fraction
from pathlib import Path

import numpy as np

from .errors import OutputError

CRF = 18  # H.264 constant rate factor: 18 is near visually lossless (0 lossless, 51 worst)
# the reasons the operating system gives ("No space left on device"), looked for in ffmpeg's words
_OS_REASONS = sorted({os.strerror(code) for code in errno.errorcode}, key=len, reverse=True)


class FfmpegPipe:
    """`ffmpeg` reading frames (uint8 (H, W, 3)) on its stdin and writing `tmp`; `path` is the
    name that errors give (the output the user asked for, not the temporary file)."""

    def __init__(self, tmp: Path, path: Path, size: tuple[int, int], fps: float):
        import imageio_ffmpeg

        self.path = path
        fps_text = str(Fraction(fps).limit_denominator())  # (a rational: 24000/1001 is not rounded)
        command = [
            imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-v", "error",
            "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{size[0]}x{size[1]}", "-pix_fmt", "rgb24",
            "-r", fps_text, "-i", "-", "-an",
            "-vcodec", "libx264", "-pix_fmt", "yuv420p",  # yuv420p: what every player decodes
            "-crf", str(CRF), "-movflags", "+faststart", str(tmp),
        ]  # fmt: skip
        # ffmpeg's messages go to a file, read when it fails (a pipe would have to be drained)
        self.errors = tempfile.TemporaryFile()
        self.process = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=self.errors,
            start_new_session=True,  # Ctrl-C in a terminal reaches raylume only, which stops ffmpeg itself
        )

    def write(self, rgb8: np.ndarray) -> None:
        try:
            self.process.stdin.write(np.ascontiguousarray(rgb8))  # (no copy: its buffer)
        except BrokenPipeError:  # ffmpeg has stopped: say why
            self._failed()

    def close(self) -> None:
        """Wait for ffmpeg to finish the video; an OutputError when it failed."""
        try:
            self.process.stdin.close()
        except BrokenPipeError:  # (the frames still buffered could not be written)
            pass
        if self.process.wait() != 0:
            self._failed()
        self.errors.close()

    def kill(self) -> None:
        """Stop ffmpeg at once and reap it (no defunct process left behind)."""
        if self.process.poll() is None:
            self.process.kill()
        try:
            self.process.stdin.close()
        except OSError:
            pass
        self.process.wait()
        self.errors.close()

    def _failed(self) -> None:
        try:  # its messages are complete once it has exited
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        raise OutputError(f"{self.path}: cannot write the file ({self._reason()})")

    def _reason(self) -> str:
        """The operating system's reason in ffmpeg's messages, else its last line, else its status."""
        self.errors.seek(0)
        text = self.errors.read().decode(errors="replace")
        for reason in _OS_REASONS:
            if reason in text:
                return reason
        lines = [re.sub(r"^\[[^\]]*\]\s*", "", line).strip() for line in text.splitlines()]
        lines = [line for line in lines if line]
        return f"ffmpeg: {lines[-1]}" if lines else f"ffmpeg exited with status {self.process.returncode}"
