"""Writing an animation's frames: an H.264 video (.mp4, through the ffmpeg that the
imageio-ffmpeg wheel carries: video_ffmpeg.py), an animated GIF (Pillow), or one image per frame
(`%04d`).

Videos are written to a temporary file beside the output and renamed into place when the last
frame is in, as every raylume output is: an interrupted render never leaves a truncated video
under the output's name.
"""

from __future__ import annotations

import os
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np

from .errors import OutputError
from .image import IMAGE_SUFFIXES, check_output_path, check_writable_folder, write_failed
from .scene.checks import SceneWarning

VIDEO_SUFFIXES = (".mp4", ".gif")
GIF_COLORS = 64
GIF_MAX_DELAY = 655350  # milliseconds: a GIF frame's delay is 16 bits of 1/100 s
_PATTERN = re.compile(r"%0?(\d*)d")


def is_video(path: Path) -> bool:
    return Path(path).suffix.lower() in VIDEO_SUFFIXES


def is_sequence(path: Path) -> bool:
    """An output name with a printf-style frame number, e.g. frames/f_%04d.png."""
    return "%" in Path(path).name


def check_sequence_path(path: Path) -> Path:
    """Check an image-sequence pattern before rendering: one %d / %0Nd in the file name, an
    image extension, a writable folder."""
    path = Path(path)
    if len(_PATTERN.findall(path.name)) != 1 or path.name.count("%") != 1:
        raise OutputError(
            f"{path}: an image sequence's name holds one frame number as %d or %0Nd, e.g. frames/f_%04d.png"
        )
    check_output_path(sequence_path(path, 0), allowed=IMAGE_SUFFIXES)
    return path


def sequence_path(pattern: Path, frame: int) -> Path:
    pattern = Path(pattern)
    return pattern.with_name(pattern.name % frame)


def check_video_path(path: Path, width: int, height: int) -> Path:
    path = check_output_path(path, allowed=VIDEO_SUFFIXES)
    if path.suffix.lower() == ".mp4" and (width % 2 or height % 2):
        raise OutputError(
            f"{path}: an H.264 video needs an even width and height (its colour is stored at half resolution); "
            f"the frames are {width} x {height}"
        )
    return path


def _same_gif_frame(a, b) -> bool:
    """Whether two quantized frames are the same image (Pillow would merge them)."""
    return a.tobytes() == b.tobytes() and a.getpalette() == b.getpalette()


class VideoWriter:
    """Frames (uint8 (H, W, 3)) in order -> `path` (.mp4 or .gif) at `fps`. `close()` puts the
    finished video in place; `abort(keep_as)` discards it, or keeps the frames written so far
    under the name `keep_as`."""

    def __init__(self, path: Path, width: int, height: int, fps: float):
        self.path = Path(path)
        self.size = (width, height)
        self.fps = float(fps)
        self.frames = 0
        folder = self.path.parent if str(self.path.parent) else Path(".")
        check_writable_folder(self.path)
        # (the stem cut short, as write_atomic's: a long name leaves room for its temporary's)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.stem[:100]}.", suffix=self.path.suffix, dir=folder)
        os.close(fd)
        self.tmp = Path(tmp)
        self._gif: list = []
        self._ffmpeg = None
        if self.path.suffix.lower() == ".gif" and self.fps > 50:
            warnings.warn(
                f"{self.path}: a GIF at {self.fps:g} fps: its frames' delays of under 20 ms are shown for 100 ms "
                "by most browsers, so it plays slower; write an .mp4, or 50 fps or less",
                SceneWarning,
                stacklevel=2,
            )
        if self.path.suffix.lower() == ".mp4":
            from .video_ffmpeg import FfmpegPipe

            try:
                self._ffmpeg = FfmpegPipe(self.tmp, self.path, self.size, self.fps)
            except BaseException:
                self.tmp.unlink(missing_ok=True)
                raise

    def write(self, rgb8: np.ndarray) -> None:
        if rgb8.shape != (self.size[1], self.size[0], 3) or rgb8.dtype != np.uint8:
            want = (self.size[1], self.size[0], 3)
            raise ValueError(f"a frame must be uint8 {want}, got {rgb8.dtype} {rgb8.shape}")
        if self._ffmpeg is not None:
            self._ffmpeg.write(rgb8)
        else:
            from PIL import Image as PILImage

            # an adaptive palette of GIF_COLORS per frame, without dithering: a GIF is a preview,
            # and 64 colours take half the bytes of 255 (dither noise would defeat LZW)
            self._gif.append(PILImage.fromarray(rgb8).quantize(colors=GIF_COLORS, dither=PILImage.Dither.NONE))
        self.frames += 1

    def _finish(self) -> None:
        if self._ffmpeg is not None:
            self._ffmpeg.close()  # an OutputError when ffmpeg could not finish the video
            self._ffmpeg = None
        elif self._gif:
            first, *rest = self._gif
            try:
                first.save(self.tmp, format="GIF", save_all=True, append_images=rest, duration=self._gif_delays(),
                           loop=0, optimize=True)  # fmt: skip
            except OverflowError:  # (frames Pillow merges that _gif_delays did not see as the same)
                raise OutputError(
                    f"{self.path}: a GIF shows one image for at most {GIF_MAX_DELAY / 1000:g} s; "
                    "write an .mp4 for this animation"
                ) from None
            self._gif = []

    def _gif_delays(self) -> list[int]:
        """Each frame's delay in milliseconds (GIF delays are in 1/100 s, at least 10 ms). Pillow
        merges a run of identical frames into one, adding their delays, and a GIF holds at most
        GIF_MAX_DELAY: a run (or one frame, at a low fps) that would show longer is shortened to
        that, with a warning, rather than failing after every frame is rendered."""
        delay = max(int(round(1000.0 / self.fps)), 10)
        delays, shortened, start = [], [], 0
        for i in range(1, len(self._gif) + 1):
            if i < len(self._gif) and _same_gif_frame(self._gif[i - 1], self._gif[i]):
                continue
            run = i - start
            each = delay if run * delay <= GIF_MAX_DELAY else max(GIF_MAX_DELAY // run // 10 * 10, 10)
            if each < delay:
                shortened.append((start, i - 1, run * delay / 1000))
            delays += [each] * run
            start = i
        if shortened:
            a, b, seconds = shortened[0]
            frames = f"frame {a}" if a == b else f"frames {a}..{b} (the same image)"
            warnings.warn(
                f"{self.path}: {frames} would show for {seconds:g} s, and a GIF shows one image for at most "
                f"{GIF_MAX_DELAY / 1000:g} s: shortened to that ({len(shortened)} such); .mp4 keeps the timing",
                SceneWarning,
                stacklevel=2,
            )
        return delays

    def close(self) -> Path:
        try:
            if self.frames == 0:
                raise OutputError(f"{self.path}: no frames were rendered")
            self._finish()
            os.chmod(self.tmp, 0o644 & ~_umask())
            os.replace(self.tmp, self.path)
        except BaseException as exc:
            self.abort()
            if isinstance(exc, OSError):  # (Pillow's, on a full disk): said as every output says it
                raise write_failed(self.path, exc) from None
            raise
        return self.path

    def abort(self, keep_as: Path | None = None) -> Path | None:
        try:
            if keep_as is not None and self.frames:
                self._finish()
                os.chmod(self.tmp, 0o644 & ~_umask())  # (mkstemp made it 0600), as close() does
                os.replace(self.tmp, keep_as)
                return keep_as
        except Exception:
            pass
        finally:
            if self._ffmpeg is not None:
                self._ffmpeg.kill()
                self._ffmpeg = None
            self.tmp.unlink(missing_ok=True)
        return None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
