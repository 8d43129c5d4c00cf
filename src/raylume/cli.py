"""The `raylume` command: render a scene, a mesh file or a built-in scene; list the built-in scenes."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import signal
import sys
import threading
import time
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperArgument, TyperCommand, TyperGroup

from .errors import OutputError, RaylumeError, SceneError


class _CleanHelp:
    """Shows --help as the flag it is: no `<bool>` type beside it in the help text. A flag that
    cannot be parsed (`--spp abc`, an unknown option, a missing value) is bad input like any
    other: one line `raylume: error: ...` and exit status 2, not Typer's boxed usage text."""

    def get_help_option(self, ctx):
        option = super().get_help_option(ctx)
        if option is not None:
            option.metavar = ""
        return option

    def parse_args(self, ctx, args):
        given = list(args)
        try:
            return super().parse_args(ctx, args)
        except _UsageError as exc:
            _fail_usage(exc, ctx, given)


def _fail_usage(exc, ctx, args: list[str]) -> None:
    command = "raylume" if ctx.parent is None else f"raylume {ctx.info_name}"
    _fail(f"{_usage_text(exc, args)} (see {command} --help)")


class _Group(_CleanHelp, TyperGroup):
    def resolve_command(self, ctx, args):
        try:
            return super().resolve_command(ctx, args)
        except _UsageError as exc:  # no such command
            _fail_usage(exc, ctx, list(args))


class _Command(_CleanHelp, TyperCommand):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        for param in self.params:
            if isinstance(param, TyperArgument) and param.metavar:
                param.display_type_rich = lambda ctx: None  # the metavar says it all; no `<str>` beside it
                if param.required and param.nargs == 1:
                    # the usage line as click writes it, `raylume convert [OPTIONS] IN`: Typer 0.2x
                    # braces a required argument (`{IN}`), which reads as literal text
                    param.get_usage_pieces = lambda ctx, name=param.metavar: [name]


app = typer.Typer(
    cls=_Group,
    add_completion=False,
    help="Render declarative 3D scenes by ray casting, Whitted ray tracing, path tracing or rasterization; "
    "view them live in the browser, animate them, render them on a cluster.",
    pretty_exceptions_enable=False,
)

EXIT_BAD_INPUT = 2
FLAG = ""  # metavar of an on/off flag: nothing follows it on the command line
# Loading compiled kernels from Numba's cache takes a fraction of this; compiling them, tens of seconds.
NOTICE_AFTER = 0.5


def compiling_notice(what: str, mode: str) -> str:
    """The line shown while Numba compiles: what, and that it happens once (then cached).
    `what`: the status a render reports ("compiling": the mode's kernels; "compiling the BVH
    builder")."""
    if what == "compiling":
        return f"compiling the {mode}-mode kernels (once per mode and kind of scene, then cached)..."
    return f"{what} (once, then cached)..."


def _fail(message: str) -> None:
    typer.echo(f"raylume: error: {message}", err=True)
    raise typer.Exit(EXIT_BAD_INPUT)


# click's UsageError, the base of Typer's BadParameter: Typer's own copy of click where it has one
_UsageError = typer.BadParameter.__bases__[0]


def _usage_text(exc, args: list[str]) -> str:
    """A usage error in one line: `--spp abc: Input should be a valid integer ...`, `No such
    option: --bogus`."""
    param = getattr(exc, "param", None)
    if isinstance(exc, typer.BadParameter) and not exc.message.strip():  # a required option left out
        return " ".join(exc.format_message().split())
    if isinstance(exc, typer.BadParameter) and param is not None and getattr(param, "opts", None):
        value = _given_value(args, param.opts)
        name = "/".join(param.opts) if value is None else f"{_given_option(args, param.opts)} {value}"
        return f"{name}: {' '.join(exc.message.split())}"
    return " ".join(exc.format_message().split()) or "bad command line"


def _given_option(args: list[str], opts: list[str]) -> str:
    """How the option was spelled (`-o` or `--output`), its last time: the value that counts."""
    given = [a.split("=", 1)[0] for a in args if a in opts or a.split("=", 1)[0] in opts]
    return given[-1] if given else opts[0]


def _given_value(args: list[str], opts: list[str]) -> str | None:
    """The text given for an option (`--spp abc` or `--spp=abc`), None where it is not an
    option's; the last one where it is given twice (click keeps the last)."""
    found = None
    for k, arg in enumerate(args):
        if arg in opts and k + 1 < len(args):
            found = args[k + 1]
        name, sep, value = arg.partition("=")
        if sep and name in opts:
            found = value
    return found


def _warn(message: str) -> None:
    typer.echo(f"raylume: warning: {message}", err=True)


def _error_text(exc: Exception) -> str:
    """An unexpected ValueError or OSError in words: no class name, and for an OSError the
    file it concerns and its reason (strerror), e.g. 'out.png: No space left on device'."""
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    return str(exc) or "unexpected error"


@contextmanager
def _errors_exit_2(debug: bool, assignments: list[str] | None = None):
    """Bad input (a RaylumeError, or an unexpected ValueError or OSError) becomes one paragraph
    on stderr and exit status 2; --debug shows the traceback instead. A scene's error that a
    --set of `assignments` caused after validation (a texture file) says which one."""
    try:
        yield
    except RaylumeError as exc:
        if debug:
            raise
        _raise_if_interrupted()  # (an error of a library that swallowed a Ctrl-C is the Ctrl-C)
        if isinstance(exc, SceneError) and assignments:
            from .scene.overrides import attributed

            _fail(attributed(str(exc), assignments))
        _fail(str(exc))
    except (ValueError, OSError) as exc:
        if debug:
            raise
        _raise_if_interrupted()
        _fail(_error_text(exc))


def _raise_if_interrupted() -> None:
    if _INTERRUPTED.is_set():
        raise KeyboardInterrupt


@app.callback(invoke_without_command=True)
def _main(
    ctx: typer.Context,
    version: Annotated[
        bool, typer.Option("--version", help="Print the version and exit", is_eager=True, metavar=FLAG)
    ] = False,
) -> None:
    """Render declarative 3D scenes by ray casting, Whitted ray tracing, path tracing or rasterization."""
    if version:
        from . import __version__

        typer.echo(f"raylume {__version__}")
        raise typer.Exit()
    if ctx.invoked_subcommand is None:  # bare `raylume`: show what it can do
        typer.echo(ctx.get_help())
        raise typer.Exit()


def _parse_aovs(specs: list[str], output: Path) -> tuple[dict[str, Path], list[str]]:
    """--aov NAME=PATH (an .npy file) or --aov NAME (a layer of the .exr output) -> the .npy
    paths by name, and the names to write as EXR layers."""
    from .image import check_output_path
    from .render import AOV_NAMES, RENDER_AOVS

    files: dict[str, Path] = {}
    layers: list[str] = []
    for spec in specs:
        name, sep, path = spec.partition("=")
        if name not in (*AOV_NAMES, *RENDER_AOVS):
            raise OutputError(f"--aov {spec}: unknown AOV {name!r}; available: {', '.join((*AOV_NAMES, *RENDER_AOVS))}")
        if sep and not path:
            raise OutputError(f"--aov {spec}: expected NAME=PATH, e.g. --aov {name}={name}.npy")
        if sep:
            if name in files:  # (the last one alone was written, without a word)
                raise OutputError(f"--aov {spec}: --aov {name}={files[name]} names the {name} AOV's file already")
            files[name] = check_output_path(path, allowed=(".npy",))
        elif output.suffix.lower() != ".exr":
            raise OutputError(
                f"--aov {name}: an AOV without =PATH is written as layers of an .exr output, and {output} is not "
                f".exr; give it a file (--aov NAME=PATH, e.g. --aov {name}={name}.npy) or write -o "
                f"{output.with_suffix('.exr').name}"
            )
        elif name not in layers:
            layers.append(name)
    return files, layers


# --define, as render, view and convert take it
DefinesOption = Annotated[
    list[str] | None,
    typer.Option(
        "--define",
        "-D",
        metavar="NAME=VALUE",
        help="Set the parameter $NAME of a Mitsuba scene (.xml), as Mitsuba's -D (repeatable)",
    ),
]


def _parse_defines(specs: list[str] | None) -> dict[str, str]:
    """--define NAME=VALUE ... as {NAME: VALUE} (Mitsuba's -D)."""
    defines = {}
    for spec in specs or []:
        name, sep, value = spec.partition("=")
        if not sep or not name.strip():
            raise SceneError(f"--define {spec}: expected NAME=VALUE, e.g. --define spp=64")
        defines[name.strip()] = value
    return defines


def _resolve_scene(
    scene: str | None, overrides: list[str] | None = None, width=None, height=None, camera=None, defines=None
):
    """(the scene, its label) for SCENE: a scene file (.toml, .json, or a Mitsuba .xml with its
    --define parameters), a glTF file (its camera, or the one --camera names:
    scene/gltf_scene.py), a mesh file (framed for the image size the flags give,
    scene/autoframe.py) or a built-in name (scene/open.py)."""
    from .scene.builtin import DEFAULT_SCENE
    from .scene.gltf import is_gltf_file
    from .scene.open import open_scene

    name = scene or DEFAULT_SCENE
    if camera is not None and not is_gltf_file(name):
        raise SceneError(f"--camera {camera}: chooses a camera of a glTF file (.gltf, .glb), and {name} is not one")
    return open_scene(name, overrides, width=width, height=height, camera=camera, defines=_parse_defines(defines))


def _check_distinct(out: Path, scene_label: str, others: list[Path]) -> None:
    paths = [out, *others]
    resolved = [p.resolve() for p in paths]
    if len(set(resolved)) != len(resolved):
        raise OutputError("two outputs (-o, --aov, --stats) name the same file")
    scene_path = Path(scene_label)
    if scene_path.exists() and scene_path.resolve() in resolved:
        raise OutputError(f"{scene_label}: an output path is the scene file itself; choose another name")


@app.command(cls=_Command)
def render(
    scene: Annotated[
        str | None,
        typer.Argument(
            metavar="SCENE",
            help="Scene file (.toml/.json), pbrt-v4 (.pbrt) or Mitsuba 3 (.xml) scene, glTF scene (.gltf .glb: its "
            "camera and lights), "
            "mesh file (.obj .ply .stl .off: framed and lit automatically) or built-in name; default: seed",
        ),
    ] = None,
    output: Annotated[
        Path, typer.Option("-o", "--output", metavar="OUT", help="Output image: .png, .jpg, .npy, .exr or .hdr")
    ] = Path("render.png"),
    width: Annotated[int | None, typer.Option("--width", metavar="W", help="Image width in pixels")] = None,
    height: Annotated[int | None, typer.Option("--height", metavar="H", help="Image height in pixels")] = None,
    spp: Annotated[int | None, typer.Option("--spp", metavar="N", help="Samples per pixel")] = None,
    mode: Annotated[str | None, typer.Option("--mode", metavar="MODE", help="cast | trace | path | raster")] = None,
    integrator: Annotated[
        str | None,
        typer.Option(
            "--integrator", metavar="NAME", help="Path mode: path (path tracing) | bdpt (bidirectional path tracing)"
        ),
    ] = None,
    max_depth: Annotated[
        int | None, typer.Option("--max-depth", metavar="D", help="Reflection/refraction depth")
    ] = None,
    seed: Annotated[int | None, typer.Option("--seed", metavar="S", help="Random seed for sampling")] = None,
    threads: Annotated[
        int | None, typer.Option("--threads", metavar="T", help="Worker threads (default: all cores)")
    ] = None,
    aov: Annotated[
        list[str] | None,
        typer.Option(
            "--aov",
            metavar="NAME[=PATH]",
            help="Write an AOV: NAME=PATH.npy, or NAME alone for a layer of the .exr output; "
            "NAME in depth, normal, object, prim, albedo, instance, noisy (the image before --denoise), spp (the "
            "samples each pixel took, with --noise-threshold or --time-limit) (repeatable)",
        ),
    ] = None,
    assignments: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            metavar="KEY=VALUE",
            help="Set a scene key before validation, e.g. camera.fov=40 or objects.0.radius=0.5; "
            "VALUE is read as TOML (repeatable)",
        ),
    ] = None,
    defines: DefinesOption = None,
    stats: Annotated[
        Path | None, typer.Option("--stats", metavar="PATH", help="Write render statistics as JSON")
    ] = None,
    bit_depth: Annotated[
        int, typer.Option("--bit-depth", metavar="8|16", help="Bits per channel of a .png output")
    ] = 8,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", metavar=FLAG, help="No progress bar or summary")] = False,
    partial: Annotated[
        bool, typer.Option("--partial", metavar=FLAG, help="On Ctrl-C, save the rows done as OUT.partial.EXT")
    ] = False,
    exposure: Annotated[
        float | None,
        typer.Option("--exposure", metavar="STOPS", help="Exposure for .png/.jpg output (2**STOPS times brighter)"),
    ] = None,
    filter: Annotated[
        str | None,
        typer.Option("--filter", metavar="FILTER", help="Pixel filter for spp > 1: box | gaussian | mitchell"),
    ] = None,
    tonemap: Annotated[
        str | None,
        typer.Option(
            "--tonemap",
            metavar="NAME",
            help="Tone mapping for .png/.jpg output, after --exposure: none (clip at 1) | reinhard | aces | agx | "
            "neutral",
        ),
    ] = None,
    denoise: Annotated[
        bool | None,
        typer.Option(
            "--denoise",
            metavar=FLAG,
            help="Path mode: denoise with Intel Open Image Denoise (guided by the albedo and normal AOVs)",
        ),
    ] = None,
    noise_threshold: Annotated[
        float | None,
        typer.Option(
            "--noise-threshold",
            metavar="E",
            help="Adaptive sampling: stop sampling a 16 x 16 tile once its noise is below E (e.g. 0.01); --spp "
            "is then the most a pixel takes",
        ),
    ] = None,
    min_spp: Annotated[
        int | None,
        typer.Option(
            "--min-spp",
            metavar="N",
            help="Adaptive sampling: samples every pixel takes before its tile may stop (default: 40 at "
            "--noise-threshold 0.05, 64 at 0.01)",
        ),
    ] = None,
    time_limit: Annotated[
        float | None,
        typer.Option(
            "--time-limit",
            metavar="SECONDS",
            help="Stop sampling after SECONDS of rendering; --spp is the most a pixel takes",
        ),
    ] = None,
    crop: Annotated[
        str | None,
        typer.Option(
            "--crop",
            metavar="X0:X1,Y0:Y1",
            help="Render only pixel columns X0..X1-1 and rows Y0..Y1-1; the output is that window of the full image",
        ),
    ] = None,
    cluster: Annotated[
        str | None,
        typer.Option(
            "--cluster",
            metavar="ADDRESS",
            help="Render in tiles on a Dask cluster: tcp://HOST:PORT of a `dask scheduler`, `local` or `local:N` "
            "(N local worker processes); the image is bit-identical to an in-process render",
        ),
    ] = None,
    frames: Annotated[
        str | None,
        typer.Option(
            "--frames", metavar="A:B", help="Animation: render frames A to B-1 (into -o out.mp4 or f_%04d.png)"
        ),
    ] = None,
    frame: Annotated[
        int | None, typer.Option("--frame", metavar="K", help="Animation: render frame K (from 0) as a still")
    ] = None,
    camera: Annotated[
        str | None, typer.Option("--camera", metavar="NAME", help="glTF scene: render through the camera NAME")
    ] = None,
    debug: Annotated[bool, typer.Option("--debug", metavar=FLAG, help="Show tracebacks of errors")] = False,
) -> None:
    """Render SCENE to an image (default: the built-in `seed` scene to render.png)."""
    from .render_window import RenderInterrupted
    from .settings import overrides_of

    flags = overrides_of(locals())  # --width ... --denoise, by the [render] keys they set
    with _terminate_as_interrupt(), _interrupts_remembered():  # SIGTERM as Ctrl-C, below
        try:
            with _errors_exit_2(debug, assignments), _echo_warnings(once=True):  # (an animation's frames: once each)
                _render(
                    scene,
                    output,
                    flags,
                    threads=threads,
                    aov_specs=aov or [],
                    stats_path=stats,
                    quiet=quiet,
                    assignments=assignments or [],
                    bit_depth=bit_depth,
                    crop=crop,
                    cluster=cluster,
                    frames=frames,
                    frame=frame,
                    partial=partial,
                    camera=camera,
                    defines=defines,
                )
        except RenderInterrupted as exc:
            _interrupted(exc, output if partial else None, bit_depth)
        except KeyboardInterrupt:
            _interrupted_before_the_end()
        except typer.Exit:
            raise  # (an animation's own interrupted line, said already: not a second one)
        except Exception:
            if not _INTERRUPTED.is_set():
                raise
            _interrupted_before_the_end()  # what a library broke by swallowing the Ctrl-C (trimesh)


def _interrupted_before_the_end() -> None:
    """Ctrl-C outside the render's rows: exit 130, saying which outputs were written before it."""
    if _WRITTEN:
        typer.echo(f"raylume: interrupted after writing {', '.join(map(str, _WRITTEN))}; nothing more", err=True)
    else:
        typer.echo("raylume: interrupted; nothing written", err=True)
    raise typer.Exit(130) from None


@contextmanager
def _terminate_as_interrupt():
    """SIGTERM (`kill`, a job scheduler, a container stopping) stops a render as Ctrl-C does:
    the temporary files removed, ffmpeg stopped, a message, and exit status 143 (128 + 15) for
    the 130 of Ctrl-C. Its default action had ended Python at once, leaving them behind. Only
    here, in the command: raylume used as a library leaves SIGTERM to its program."""
    if threading.current_thread() is not threading.main_thread():  # (signals go to the main thread)
        yield
        return
    received = []

    def interrupt(signum, frame):
        if not received:  # once: a second SIGTERM does not cut the clean-up short
            received.append(signum)
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    previous = signal.SIG_DFL if previous is None else previous  # (None: set outside Python)
    try:
        yield
    except typer.Exit as exc:
        if received and exc.exit_code == 130:  # the Ctrl-C path ran: exit as SIGTERM's
            raise typer.Exit(128 + signal.SIGTERM) from None
        raise
    finally:
        signal.signal(signal.SIGTERM, previous)


# Set by Ctrl-C during `raylume render`; _DEFERRED while a Ctrl-C that came during an import waits
# for the render's next stage (_interrupts_remembered).
_INTERRUPTED = threading.Event()
_DEFERRED = threading.Event()
_WRITTEN: list[Path] = []  # the outputs `raylume render` has written, for its Ctrl-C message


def _importing(frame) -> bool:
    """Whether the interrupted frame runs inside an import (Python's import machinery)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


@contextmanager
def _interrupts_remembered():
    """Ctrl-C during an import is held until the import ends: trimesh's optional imports catch
    BaseException, so a KeyboardInterrupt raised inside them (reading a mesh file, the first time)
    was lost and the render went on to the end, or broke trimesh, whose import then failed with
    a TypeError. The render raises it at its next stage (the status callbacks of
    _compile_notice, and after the scene is read). Elsewhere Ctrl-C raises at once, as by
    default; an error that follows one is the Ctrl-C's doing (the render command's handler)."""
    if threading.current_thread() is not threading.main_thread():  # (signals go to the main thread)
        yield
        return
    _INTERRUPTED.clear()
    _DEFERRED.clear()
    _WRITTEN.clear()

    def interrupt(signum, frame):
        _INTERRUPTED.set()
        if _importing(frame):
            _DEFERRED.set()
            return
        raise KeyboardInterrupt

    def unraisable(info):
        # a Ctrl-C that lands in a ctypes callback or a finaliser (Numba's object cache, llvmlite's
        # strings while kernels load) is printed as "Exception ignored ...": 8 lines of noise
        if not _INTERRUPTED.is_set():
            previous_hook(info)

    previous = signal.signal(signal.SIGINT, interrupt)
    previous = signal.default_int_handler if previous is None else previous
    previous_hook, sys.unraisablehook = sys.unraisablehook, unraisable
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = previous_hook
        _INTERRUPTED.clear()  # (a later command in this process starts afresh)
        _DEFERRED.clear()
        _WRITTEN.clear()


def _check_interrupted() -> None:
    """Raise a Ctrl-C that came during an import (_interrupts_remembered), once."""
    if _DEFERRED.is_set():
        _DEFERRED.clear()
        raise KeyboardInterrupt


def _interrupted(exc, output: Path | None, bit_depth: int) -> None:
    """Ctrl-C: exit 130, after saving the rows done as OUT.partial.EXT when --partial asks."""
    if output is None:
        typer.echo("raylume: interrupted; nothing written", err=True)
        raise typer.Exit(130)
    path = output.with_name(f"{output.stem}.partial{output.suffix}")
    try:
        exc.image.save(path, bit_depth=bit_depth)
    except RaylumeError as error:
        typer.echo(f"raylume: interrupted; the partial image was not saved: {error}", err=True)
        raise typer.Exit(130) from None
    typer.echo(f"raylume: interrupted after {exc.done}; saved {path}", err=True)
    raise typer.Exit(130)


def _render(
    scene: str | None,
    output: Path,
    flags: dict,
    *,
    threads: int | None,
    aov_specs: list[str],
    stats_path: Path | None,
    quiet: bool,
    assignments: list[str],
    bit_depth: int,
    crop: str | None,
    cluster: str | None,
    frames: str | None,
    frame: int | None,
    partial: bool,
    camera: str | None,
    defines: list[str] | None = None,
) -> None:
    """`raylume render`: `flags` are the [render] values given as flags (settings.OVERRIDES)."""
    from .image import check_bit_depth, check_output_path, save_npy, write_atomic
    from .render import RENDER_AOVS
    from .render import render as render_scene
    from .settings import adaptive_ignored, resolve_settings, samples_adaptively
    from .video import check_sequence_path, is_sequence, is_video

    # Every output is checked before the scene is even read: a render is never lost to a bad path.
    animated = is_video(output) or (is_sequence(output) and frame is None)
    if is_sequence(output):
        output = check_sequence_path(output)
    elif not is_video(output):
        output = check_output_path(output, also="; for an animation .mp4, .gif, or frames like f_%04d.png")
    if frames is not None and frame is not None:
        raise OutputError("--frames A:B and --frame K exclude each other: several frames, or one still")
    if frames is not None and not animated:
        raise OutputError(
            f"--frames {frames}: several frames go into a video (-o out.mp4) or an image sequence "
            f"(-o frames/f_%04d.png), not into {output}"
        )
    if frame is not None and is_video(output):
        raise OutputError(f"--frame {frame} renders a still: write it to an image (-o frame.png), not to {output}")
    if animated and (aov_specs or crop):
        raise OutputError(f"{output}: --aov and --crop are for stills; render one frame with --frame K for them")
    check_bit_depth(output, bit_depth)  # (an animation's too: videos had been silently 8-bit)
    aov_paths, layers = _parse_aovs(aov_specs, output)
    if stats_path is not None:
        stats_path = check_output_path(stats_path, allowed=(".json",))
    if cluster is not None:
        from .cluster import parse_address

        parse_address(cluster)  # a malformed address fails before anything is read
    started = time.perf_counter()
    scene_model, label = _resolve_scene(scene, assignments, flags.get("width"), flags.get("height"), camera, defines)
    _check_interrupted()
    _check_distinct(output, scene or "", [*aov_paths.values(), *([stats_path] if stats_path else [])])
    settings = resolve_settings(scene_model, flags, threads=threads, crop=_parse_crop(crop), source=label, flags=True)
    parse_seconds = time.perf_counter() - started
    table = settings.render
    denoised = table.denoise and table.mode == "path"
    if "noisy" in (*aov_paths, *layers) and not denoised:
        raise OutputError("--aov noisy is the image before denoising: it needs --denoise and path mode (--mode path)")
    if "spp" in (*aov_paths, *layers) and not samples_adaptively(table, on_cluster=cluster is not None):
        why = adaptive_ignored(table, on_cluster=cluster is not None) or "it needs --noise-threshold or --time-limit"
        raise OutputError(f"--aov spp is the samples each pixel took in an adaptive render: {why}")
    if denoised:
        from .denoise import require_denoiser

        require_denoiser()  # a missing package fails now, not after the render
    _warn_ignored(output, table, flags)
    if animated or frame is not None:
        from .animation import animation_of, camera_at

        if is_video(output) and scene_model.animation is None:
            raise OutputError(
                f"{output}: unknown output format {output.suffix!r} for a still image: {output.suffix} is for "
                f"animations, and {label} has no [animation] table; use one of .png, .jpg, .npy, .exr, .hdr"
            )
        animation_of(scene_model, label)  # no [animation]: an error before anything renders
    if cluster is not None:
        from .cluster import connect

        connect(cluster)  # an unreachable scheduler fails now, before the scene is compiled
    if animated:
        from .cli_animation import render_animation_to

        render_animation_to(
            scene_model, label, output, frames, settings, cluster=cluster, quiet=quiet, partial=partial,
            stats_path=stats_path, progress_bar=_progress, compile_notice=_compile_notice, bit_depth=bit_depth,
        )  # fmt: skip
        return
    if frame is not None:
        scene_model = scene_model.replace(camera=camera_at(scene_model, frame, label))
        if is_sequence(output):
            from .video import sequence_path

            output = sequence_path(output, frame)
    elif scene_model.animation is not None:
        _warn(
            f"{label} has an [animation] of {scene_model.animation.frames} frames; this renders the still of "
            "[camera]: write a video (-o out.mp4), a sequence (-o frames/f_%04d.png) or one frame (--frame K)"
        )

    with _progress(quiet) as progress, _compile_notice(quiet, mode=settings.render.mode) as status:
        image = render_scene(
            scene_model,
            aovs=bool(set(aov_paths) - set(RENDER_AOVS) or set(layers) - set(RENDER_AOVS)),
            progress=progress,
            source=label,
            status=status,
            cluster=cluster,
            settings=settings,
        )
    image.stats["parse_seconds"] = parse_seconds
    _WRITTEN.append(image.save(output, bit_depth=bit_depth, layers=layers))
    for name, path in aov_paths.items():
        _WRITTEN.append(save_npy(path, image.aovs[name]))
    if stats_path is not None:
        text = json.dumps(_json_safe(image.stats), indent=2) + "\n"
        write_atomic(stats_path, lambda fh: fh.write(text.encode()))
        _WRITTEN.append(stats_path)
    if not quiet:
        line = summary(output, image.stats)
        if "cluster" in image.stats:
            c = image.stats["cluster"]
            line += (
                f"; on {c['workers']} workers ({c['tiles']} tiles, first in {c['first_tile_seconds'] or 0:.2f} s, "
                f"{c['wall_seconds']:.2f} s wall)"
            )
        typer.echo(line, err=True)


def _parse_crop(text: str | None) -> tuple[int, int, int, int] | None:
    """(x0, x1, y0, y1) of `--crop X0:X1,Y0:Y1` (checked against the image size with the settings)."""
    if text is None:
        return None
    try:
        columns, rows = text.split(",")
        x0, x1 = (int(v) for v in columns.split(":"))
        y0, y1 = (int(v) for v in rows.split(":"))
    except ValueError:
        raise OutputError(f"--crop {text}: expected X0:X1,Y0:Y1 in pixels, e.g. --crop 100:300,50:250") from None
    return x0, x1, y0, y1


def _warn_ignored(output: Path, settings, flags: dict) -> None:
    """Flags given but without effect on this render get a one-line warning, not silence."""
    from .image import ENCODED_SUFFIXES
    from .video import is_video

    pixel_filter = flags.get("filter")
    encoded = output.suffix.lower() in ENCODED_SUFFIXES or is_video(output)  # (videos are 8-bit frames)
    if flags.get("min_spp") is not None and settings.noise_threshold is None:
        _warn("--min-spp has no effect without a noise threshold (--noise-threshold)")
    for flag in ("exposure", "tonemap"):
        if flags.get(flag) is not None and not encoded:
            _warn(
                f"--{flag} applies to {', '.join(ENCODED_SUFFIXES)} and video outputs only; {output} stores the "
                "linear values as rendered"
            )
    if pixel_filter is not None and settings.mode == "raster":
        _warn("--filter has no effect in raster mode: it takes one sample at each pixel centre")
    elif pixel_filter is not None and settings.spp == 1:
        _warn("--filter has no effect with spp 1: the one sample is the pixel centre; use --spp 4 or more")
    if flags.get("denoise") and settings.mode != "path":
        _warn(f"--denoise has no effect in {settings.mode} mode: it denoises path-traced images (--mode path)")
    if flags.get("integrator") is not None and settings.mode != "path":
        _warn(f"--integrator has no effect in {settings.mode} mode: it picks path mode's (--mode path)")


def summary(output: Path, s: dict) -> str:
    """The line printed after a render. A rasterizer traces no rays, so it gets no ray rate.
    Compilation (JIT, or loading the kernels from the cache) is reported apart from the build."""
    size = f"{output}: {s['width']}x{s['height']} {s['mode']}"
    if s.get("crop"):  # the file holds the window
        x0, x1, y0, y1 = s["crop"]
        size = f"{output}: {x1 - x0}x{y1 - y0} window of {s['width']}x{s['height']} {s['mode']}"
    build = f"build {s['build_seconds']:.3f} s"
    if "compile_seconds" in s:
        build += f", compile {s['compile_seconds']:.2f} s"
    if s["mode"] == "raster":
        return f"{size}, rasterized in {s['render_seconds']:.3f} s (no rays traced), {build}"
    rays = f"{s['rays'] / 1e6:.2f} Mrays" if s["rays"] >= 1e6 else f"{s['rays']:,} rays"
    line = f"{size}, {rays} in {s['render_seconds']:.3f} s ({s['mrays_per_second']:.1f} Mrays/s), {build}"
    if "adaptive" in s:
        a = s["adaptive"]
        why = {"noise": "every tile below the noise threshold", "spp": "spp reached", "time": "time limit"}
        line += (
            f"; adaptive: {a['mean_spp']:.1f} spp a pixel on average ({a['min_spp']}-{a['max_spp']}), "
            f"stopped by {why[a['stopped_by']]}"
        )
    return line


def _json_safe(stats: dict) -> dict:
    out = {}
    for k, v in stats.items():
        v = v.item() if hasattr(v, "item") else v
        if isinstance(v, float) and not math.isfinite(v):
            v = None
        out[k] = v
    return out


class _progress:
    """A Rich progress bar that appears only when the render takes more than a moment."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.bar = None
        self.task = None
        self.start = None

    def __enter__(self):
        import time

        self.start = time.perf_counter()
        # no bar where stderr is no terminal (a log, a pipe): Rich would leave a blank line there
        return None if self.quiet or not _stderr_console().is_terminal else self.update

    def update(self, done: int, total: int) -> None:
        import time

        if self.bar is None:
            if time.perf_counter() - self.start < 0.5 or done >= total:
                return
            from rich.progress import (
                BarColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
            )

            self.bar = Progress(
                TextColumn("rendering"),
                BarColumn(),
                TextColumn("{task.percentage:>3.0f}%"),
                TimeRemainingColumn(),
                transient=True,
                console=_stderr_console(),
            )
            self.bar.start()
            self.task = self.bar.add_task("render", total=total)
        self.bar.update(self.task, completed=done)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.stop()
        return False


def _stderr_console():
    from rich.console import Console

    return Console(stderr=True)


class _compile_notice:
    """A spinner on stderr while kernels compile (between a status "compiling..." and the next
    status), shown only when that outlasts NOTICE_AFTER seconds: loading compiled kernels from
    the cache is quicker. Where stderr is no terminal, one plain line instead."""

    def __init__(self, quiet: bool, console=None, mode: str = "trace"):
        self.quiet = quiet
        self.mode = mode
        self.console = console
        self.lock = threading.Lock()
        self.timer: threading.Timer | None = None
        self.spinner = None
        self.message = ""

    def __enter__(self):
        return self.status

    def status(self, what: str) -> None:
        _check_interrupted()  # each stage of a render passes here, quiet or not
        if self.quiet:
            return
        with self.lock:
            self._stop()
            if what.startswith("compiling"):
                self.message = compiling_notice(what, self.mode)
                self.timer = threading.Timer(NOTICE_AFTER, self._show)
                self.timer.daemon = True
                self.timer.start()

    def _show(self) -> None:
        with self.lock:
            if self.timer is not threading.current_thread():
                return  # the compilation ended while this timer fired
            self.timer = None
            console = self.console or _stderr_console()
            if console.is_terminal:
                self.spinner = console.status(self.message)
                self.spinner.start()
            else:
                console.print(f"raylume: {self.message}", markup=False, highlight=False, soft_wrap=True)

    def _stop(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None
        if self.spinner is not None:
            self.spinner.stop()
            self.spinner = None

    def __exit__(self, *exc):
        with self.lock:
            self._stop()
        return False


class _echo_warnings:
    """Scene warnings (raylume.scene.checks) as one line each on stderr, as they happen; other
    warnings go where they would have gone. `once`: each message once (the live view's render
    thread renders again and again)."""

    def __init__(self, once: bool = False):
        self.once = once
        self.said: set[str] = set()

    def __enter__(self):
        from .scene.checks import SceneWarning

        self.context = warnings.catch_warnings()
        self.context.__enter__()
        warnings.simplefilter("always", SceneWarning)  # every render's, not only the first
        shown = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, SceneWarning):
                if not (self.once and str(message) in self.said):
                    _warn(str(message))
                self.said.add(str(message))
            else:
                shown(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        return self

    def __exit__(self, *exc):
        return self.context.__exit__(*exc)


@app.command(cls=_Command)
def scenes() -> None:
    """List the built-in scenes."""
    from .scene.builtin import DEFAULT_SCENE, builtin_description, builtin_names

    for name in builtin_names():
        label = f"{name} (default)" if name == DEFAULT_SCENE else name
        typer.echo(f"{label:<16} {builtin_description(name)}")


@app.command(cls=_Command)
def view(
    scene: Annotated[
        str | None,
        typer.Argument(
            metavar="SCENE",
            help="Scene file (.toml/.json/.pbrt/.xml), glTF or mesh file or built-in name; default: seed",
        ),
    ] = None,
    mode: Annotated[
        str | None, typer.Option("--mode", metavar="MODE", help="cast | trace | path | raster (switchable on the page)")
    ] = None,
    integrator: Annotated[
        str | None,
        typer.Option(
            "--integrator", metavar="NAME", help="Path mode: path (path tracing) | bdpt (bidirectional path tracing)"
        ),
    ] = None,
    width: Annotated[int | None, typer.Option("--width", metavar="W", help="Image width in pixels")] = None,
    height: Annotated[int | None, typer.Option("--height", metavar="H", help="Image height in pixels")] = None,
    spp: Annotated[
        int | None, typer.Option("--spp", metavar="N", help="Samples per pixel at rest (path mode: per film)")
    ] = None,
    denoise: Annotated[
        bool | None,
        typer.Option(
            "--denoise",
            metavar=FLAG,
            help="Path mode: show frames denoised, by SVGF while the camera moves and by Intel Open Image "
            "Denoise at rest (switchable on the page)",
        ),
    ] = None,
    tonemap: Annotated[
        str | None,
        typer.Option(
            "--tonemap", metavar="NAME", help="Tone mapping of the frames: none | reinhard | aces | agx | neutral"
        ),
    ] = None,
    port: Annotated[int, typer.Option("--port", metavar="P", help="Port to listen on; 0 picks a free one")] = 8765,
    host: Annotated[
        str, typer.Option("--host", metavar="ADDR", help="Address to listen on (other than loopback: with a warning)")
    ] = "127.0.0.1",
    no_browser: Annotated[
        bool, typer.Option("--no-browser", metavar=FLAG, help="Print the URL only; do not open a browser")
    ] = False,
    assignments: Annotated[
        list[str] | None,
        typer.Option("--set", metavar="KEY=VALUE", help="Set a scene key, as for render (repeatable)"),
    ] = None,
    defines: DefinesOption = None,
    threads: Annotated[
        int | None, typer.Option("--threads", metavar="T", help="Render threads (default: all cores)")
    ] = None,
    debug: Annotated[bool, typer.Option("--debug", metavar=FLAG, help="Show tracebacks of errors")] = False,
) -> None:
    """Serve a live, progressive view of SCENE in the browser (drag: orbit, right/shift-drag: pan, wheel: dolly)."""
    from .scene.checks import warn_about
    from .settings import is_adaptive, overrides_of, resolve_settings
    from .viewer.command import run_view

    flags = overrides_of(locals())  # --width, --height, --spp, --mode, --denoise, --tonemap
    try:
        # (the render thread's warnings too, as render prints them: one line each, and once)
        with _errors_exit_2(debug, assignments), _echo_warnings(once=True):
            scene_model, label = _resolve_scene(scene, assignments or [], width, height, defines=defines)
            settings = resolve_settings(scene_model, flags, threads=threads, source=label, flags=True)
            warn_about(scene_model, settings.render.mode)  # a view's passes do not all go through render()
            if is_adaptive(settings.render):
                _warn(
                    f"{label} sets noise_threshold or time_limit, which raylume render uses: the live view "
                    "gives every pixel its spp"
                )
                plain = {"noise_threshold": None, "time_limit": None}  # (no second warning from its renders)
                scene_model = scene_model.replace(render=plain)
                settings = dataclasses.replace(settings, render=settings.render.model_copy(update=plain))
            code = run_view(scene_model, label, settings, host=host, port=port, open_browser=not no_browser)
    except KeyboardInterrupt:
        raise typer.Exit(130) from None
    raise typer.Exit(code)


@app.command(cls=_Command)
def convert(
    scene: Annotated[
        str,
        typer.Argument(
            metavar="IN",
            help="Any scene raylume reads: a .toml/.json scene file, a pbrt-v4 .pbrt or Mitsuba 3 .xml scene, "
            "a glTF or mesh file, a built-in name",
        ),
    ],
    output: Annotated[
        Path, typer.Option("-o", "--output", metavar="OUT", help="The raylume scene file to write: .toml or .json")
    ],
    assignments: Annotated[
        list[str] | None,
        typer.Option("--set", metavar="KEY=VALUE", help="Set a scene key, as for render (repeatable)"),
    ] = None,
    defines: DefinesOption = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", metavar=FLAG, help="No line saying what was written")] = False,
    debug: Annotated[bool, typer.Option("--debug", metavar=FLAG, help="Show tracebacks of errors")] = False,
) -> None:
    """Write IN as a raylume scene file that renders the same image as IN.

    Meshes and images stay where they are, referenced by path."""
    from .save import save_scene
    from .scene.export import SUFFIXES

    with _errors_exit_2(debug, assignments), _echo_warnings():
        if output.suffix.lower() not in SUFFIXES:
            raise OutputError(f"-o {output}: a raylume scene file ends in .toml or .json")
        scene_model, label = _resolve_scene(scene, assignments or [], defines=defines)
        _check_distinct(output, label, [])
        save_scene(scene_model, output)
    if not quiet:
        typer.echo(f"{output}: written from {label}", err=True)


@app.command(cls=_Command)
def warmup(
    processes: Annotated[
        int | None,
        typer.Option(
            "--processes", "-j", metavar="N", help="Compile in N processes side by side (default: one per core)"
        ),
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", metavar=FLAG, help="Print nothing")] = False,
) -> None:
    """Compile every kernel (each mode, each kind of scene) into Numba's cache now, so that no later render waits."""
    from .warmup import warm_in_processes

    if processes is not None and processes < 1:
        _fail(f"--processes {processes}: expected 1 or more")
    report = None if quiet else (lambda line: typer.echo(f"raylume: warm-up: {line}", err=True))
    with _terminate_as_interrupt():  # SIGTERM as Ctrl-C: the compiling processes stopped, not orphaned
        try:
            done = warm_in_processes(processes or os.cpu_count() or 1, report)
        except KeyboardInterrupt:
            typer.echo("raylume: warm-up interrupted; what was compiled stays in the cache", err=True)
            raise typer.Exit(130) from None
    if not done:
        _fail("the warm-up failed (see above); renders will compile their kernels when they need them")


def main() -> None:  # pragma: no cover - console entry point
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
