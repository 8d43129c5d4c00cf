"""The settings of one render, resolved once: the scene's [render] table with the caller's
overrides, the thread count and the crop window, each validated here and nowhere else.

The command line resolves them from its flags, `raylume.render`, `Session.render` and
`raylume.view` from their keyword arguments; the result, a ResolvedSettings, is what the
session, the cluster, animations and the viewer are handed.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numba
from pydantic import ValidationError

from .errors import OutputError, RaylumeError, SceneError
from .scene.model import RenderSettings, Scene
from .scene.validation_errors import format_validation_error

# The [render] keys that a render call overrides by name: keyword arguments of raylume.render,
# Session.render and raylume.view, and the command line's flags (--width, ..., --denoise).
OVERRIDES = (
    "width", "height", "spp", "mode", "integrator", "max_depth", "seed", "filter", "exposure", "tonemap",
    "denoise", "noise_threshold", "min_spp", "time_limit",
)  # fmt: skip
COMMAND_LINE = "command line"  # how errors name the source of flags


@dataclass(frozen=True)
class ResolvedSettings:
    """What one render runs with, validated: `render`, the [render] table with the overrides;
    `threads`, the lanes to run on (every core unless asked); `crop`, the window (x0, x1, y0, y1)
    asked for, or None for the whole image."""

    render: RenderSettings
    threads: int
    crop: tuple[int, int, int, int] | None = None

    @property
    def window(self) -> tuple[int, int, int, int]:
        """(x0, x1, y0, y1) of the pixels rendered: the crop, or the whole image."""
        return self.crop if self.crop is not None else (0, self.render.width, 0, self.render.height)


def resolve_settings(
    base: Scene | RenderSettings,
    overrides: Mapping[str, Any] | None = None,
    *,
    threads: int | None = None,
    crop: tuple[int, int, int, int] | None = None,
    source: str = "<scene>",
    flags: bool = False,
) -> ResolvedSettings:
    """The settings of one render of `base` (a scene, or a [render] table), `overrides`
    ({key: value}; None values are left out) replacing its [render] keys. A bad value is a
    SceneError naming the key; a bad thread count or crop says what is allowed. `flags`: the
    values came from the command line, and errors name its flags (`--max-depth`) instead of
    `source`'s render settings."""
    table = base.render if isinstance(base, Scene) else base
    values = {key: value for key, value in (overrides or {}).items() if value is not None}
    if values.get("mode") == "trace" and table.max_depth == -1 and "max_depth" not in values:
        # the scene's depth, not the mode asked for, is what to change: name its key
        depth = "--max-depth N" if flags else "max_depth=N"
        raise SceneError(
            f"{source}: render.max_depth: -1 (unlimited) is for path mode; trace mode needs a depth >= 0 (give {depth})"
        )
    if values:
        try:
            table = table.updated(**values)
        except ValidationError as exc:
            if flags:
                message = format_validation_error(exc, COMMAND_LINE, RenderSettings, key_name=flag_name)
            else:
                message = format_validation_error(exc, source, RenderSettings, context="render settings: ")
            raise SceneError(message) from None
    threads = check_threads(threads, flags)
    crop_source = f"{COMMAND_LINE} (--crop)" if flags else source
    window = None if crop is None else check_crop(crop, table.width, table.height, crop_source)
    return ResolvedSettings(table, threads, window)


def settings_of_call(
    base: Scene | RenderSettings,
    arguments: Mapping[str, Any],
    settings: ResolvedSettings | None = None,
    source: str = "<scene>",
) -> ResolvedSettings:
    """The settings of a render call (raylume.render, Session.render, raylume.view) from its
    `arguments` (its locals(): the OVERRIDES, `threads`, `crop`), or its `settings=` when given:
    then none of those may be given too (a TypeError)."""
    given = overrides_of(arguments)
    threads, crop = arguments.get("threads"), arguments.get("crop")
    if settings is None:
        return resolve_settings(base, given, threads=threads, crop=crop, source=source)
    also = [*given, *(["threads"] if threads is not None else []), *(["crop"] if crop is not None else [])]
    if also:
        raise TypeError(f"settings= already holds the render's settings; leave out {', '.join(also)}")
    return settings


def is_adaptive(table: RenderSettings) -> bool:
    """Whether these settings ask for adaptive sampling (raylume/adaptive.py)."""
    return table.noise_threshold is not None or table.time_limit is not None


def adaptive_ignored(table: RenderSettings, on_cluster: bool = False) -> str | None:
    """Why a render of these settings samples every pixel alike though they ask for adaptive
    sampling (None: they do not ask, or it samples adaptively)."""
    if not is_adaptive(table):
        return None
    if table.mode == "raster":
        return "raster mode draws every pixel once"
    if table.mode == "path" and table.integrator == "bdpt":
        return (
            "bdpt's light paths reach every pixel, so its tiles cannot stop apart: every pixel takes spp samples "
            "(use integrator = 'path')"
        )
    if on_cluster and table.noise_threshold is None:
        return (
            "a cluster's tiles share no clock for a time limit: every pixel takes spp samples (give "
            "noise_threshold, or leave out --cluster)"
        )
    return None


def samples_adaptively(table: RenderSettings, on_cluster: bool = False, warn_if_ignored: bool = False) -> bool:
    """Whether a render of these settings samples adaptively; `warn_if_ignored`: a SceneWarning
    saying why not, where they ask for it (and, on a cluster, that a time limit is left out)."""
    ignored = adaptive_ignored(table, on_cluster)
    if warn_if_ignored:
        from .scene.checks import warn

        if ignored:
            given = [key for key in ("noise_threshold", "time_limit") if getattr(table, key) is not None]
            warn(f"{' and '.join(given)} {'are' if len(given) > 1 else 'is'} ignored: {ignored}")
        elif on_cluster and table.time_limit is not None:
            warn("time_limit is ignored on a cluster (its tiles share no clock): noise_threshold and spp decide")
    return is_adaptive(table) and ignored is None


def overrides_of(arguments: Mapping[str, Any]) -> dict[str, Any]:
    """The OVERRIDES among a call's arguments that are given (not None)."""
    return {name: arguments[name] for name in OVERRIDES if arguments.get(name) is not None}


def flag_name(loc: tuple) -> str:
    """The command-line flag of a [render] key: ('max_depth',) -> '--max-depth'."""
    return f"--{'-'.join(str(p) for p in loc).replace('_', '-')}" if loc else ""


def is_whole_number(value) -> bool:
    """An int (numpy's too), not a bool: what a count, a thread number or a pixel index takes."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_threads(threads: int | None, flags: bool = False) -> int:
    """The lanes to run on: `threads`, which must be 1..Numba's thread count, or all of them."""
    most = numba.config.NUMBA_NUM_THREADS
    if threads is None:
        return most
    if not is_whole_number(threads):
        raise ValueError(f"threads must be a whole number between 1 and {most}, got {threads!r}")
    if not 1 <= threads <= most:
        if flags:
            raise OutputError(f"--threads {threads}: must be between 1 and {most}")
        raise ValueError(f"threads must be between 1 and {most}")
    return threads


def check_crop(crop, width: int, height: int, source: str = "<scene>") -> tuple[int, int, int, int]:
    """The window (x0, x1, y0, y1) of a crop (columns x0..x1-1, rows y0..y1-1), the whole image
    for None; a window outside the image or empty is a RaylumeError."""
    if crop is None:
        return 0, width, 0, height
    try:
        values = () if isinstance(crop, (str, bytes)) else tuple(crop)
    except TypeError:
        values = ()
    if len(values) != 4 or not all(is_whole_number(c) for c in values):
        raise RaylumeError(f"{source}: crop must be four whole numbers (x0, x1, y0, y1), got {crop!r}")
    x0, x1, y0, y1 = (int(c) for c in values)
    if not (0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height):
        raise RaylumeError(
            f"{source}: crop {x0}:{x1},{y0}:{y1} must be a non-empty window of the {width} x {height} image "
            f"(0 <= X0 < X1 <= {width}, 0 <= Y0 < Y1 <= {height})"
        )
    return x0, x1, y0, y1
