"""The `raylume` command: render, scenes (and bench, in benchmarks/)."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Annotated, Optional

import typer

from .errors import OutputError, RaylumeError, SceneError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=False,
    help="Render declarative 3D scenes by ray casting, ray tracing or rasterization.",
    pretty_exceptions_enable=False,
)

EXIT_BAD_INPUT = 2


def _fail(message: str) -> None:
    typer.echo(f"raylume: error: {message}", err=True)
    raise typer.Exit(EXIT_BAD_INPUT)


def _parse_aovs(specs: list[str]) -> dict[str, Path]:
    from .image import check_output_path
    from .render import AOV_NAMES

    out: dict[str, Path] = {}
    for spec in specs:
        name, sep, path = spec.partition("=")
        if not sep or not path:
            raise OutputError(f"--aov {spec!r}: expected NAME=PATH, e.g. --aov depth=depth.npy")
        if name not in AOV_NAMES:
            raise OutputError(f"--aov {spec!r}: unknown AOV {name!r}; available: {', '.join(AOV_NAMES)}")
        out[name] = check_output_path(path, allowed=(".npy",))
    return out


def _resolve_scene(scene: str | None):
    from .scene.builtin import DEFAULT_SCENE, builtin_names, builtin_path
    from .scene.load import SCENE_SUFFIXES, load_scene

    name = scene or DEFAULT_SCENE
    if Path(name).suffix.lower() in SCENE_SUFFIXES or os.sep in name or Path(name).exists():
        return load_scene(name), name
    if name in builtin_names():
        return load_scene(builtin_path(name)), f"built-in scene {name!r}"
    raise SceneError(
        f"{name}: not a scene file (.toml or .json) nor a built-in scene; built-ins: {', '.join(builtin_names())}"
    )


def _check_distinct(out: Path, scene_label: str, others: list[Path]) -> None:
    paths = [out, *others]
    resolved = [p.resolve() for p in paths]
    if len(set(resolved)) != len(resolved):
        raise OutputError("two outputs (-o, --aov, --stats) name the same file")
    scene_path = Path(scene_label)
    if scene_path.exists() and scene_path.resolve() in resolved:
        raise OutputError(f"{scene_label}: an output path is the scene file itself; choose another name")


@app.command()
def render(
    scene: Annotated[Optional[str], typer.Argument(help="Scene file (.toml/.json) or built-in name; default: seed")] = None,
    output: Annotated[Path, typer.Option("-o", "--output", help="Output image: .png, .npy, .exr or .hdr")] = Path("render.png"),
    width: Annotated[Optional[int], typer.Option("--width", help="Image width in pixels")] = None,
    height: Annotated[Optional[int], typer.Option("--height", help="Image height in pixels")] = None,
    spp: Annotated[Optional[int], typer.Option("--spp", help="Samples per pixel")] = None,
    mode: Annotated[Optional[str], typer.Option("--mode", help="cast | trace | raster")] = None,
    max_depth: Annotated[Optional[int], typer.Option("--max-depth", help="Reflection/refraction depth")] = None,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed for sampling")] = None,
    threads: Annotated[Optional[int], typer.Option("--threads", help="Worker threads (default: all cores)")] = None,
    aov: Annotated[Optional[list[str]], typer.Option("--aov", help="NAME=PATH.npy; NAME in depth, normal, object, prim, albedo")] = None,
    stats: Annotated[Optional[Path], typer.Option("--stats", help="Write render statistics as JSON")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar or summary")] = False,
    partial: Annotated[bool, typer.Option("--partial", help="On Ctrl-C, save the rows done as OUT.partial.EXT")] = False,
    exposure: Annotated[Optional[float], typer.Option("--exposure", help="Exposure in stops for PNG output (2**E times brighter)")] = None,
    pixel_filter: Annotated[Optional[str], typer.Option("--filter", help="Pixel filter for spp > 1: box | gaussian | mitchell")] = None,
    debug: Annotated[bool, typer.Option("--debug", help="Show tracebacks of errors")] = False,
) -> None:
    """Render SCENE to an image (default: the built-in `seed` scene to render.png)."""
    from .render import RenderInterrupted

    try:
        _render(scene, output, width, height, spp, mode, max_depth, seed, threads, aov or [], stats, quiet,
                exposure=exposure, pixel_filter=pixel_filter)
    except RenderInterrupted as exc:
        if partial:
            path = output.with_name(f"{output.stem}.partial{output.suffix}")
            exc.image.save(path)
            typer.echo(f"raylume: interrupted after {exc.rows_done} of {exc.image.height} rows; saved {path}", err=True)
        else:
            typer.echo("raylume: interrupted; nothing written", err=True)
        raise typer.Exit(130)
    except KeyboardInterrupt:
        typer.echo("raylume: interrupted; nothing written", err=True)
        raise typer.Exit(130)
    except RaylumeError as exc:
        if debug:
            raise
        _fail(str(exc))
    except (ValueError, OSError) as exc:
        if debug:
            raise
        _fail(f"{type(exc).__name__}: {exc}")


def _render(scene, output, width, height, spp, mode, max_depth, seed, threads, aov_specs, stats_path, quiet,
            exposure=None, pixel_filter=None):
    import numba
    from pydantic import ValidationError

    from .image import check_output_path, save_npy
    from .render import render as render_scene

    output = check_output_path(output)
    aov_paths = _parse_aovs(aov_specs)
    if stats_path is not None:
        stats_path = check_output_path(stats_path, allowed=(".json",))
    scene_model, label = _resolve_scene(scene)
    _check_distinct(output, scene or "", [*aov_paths.values(), *([stats_path] if stats_path else [])])
    if threads is not None and not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
        raise OutputError(f"--threads {threads}: must be between 1 and {numba.config.NUMBA_NUM_THREADS}")
    try:
        scene_model = scene_model.with_render(
            width=width, height=height, spp=spp, mode=mode, max_depth=max_depth, seed=seed,
            exposure=exposure, filter=pixel_filter,
        )
    except ValidationError as exc:
        problems = "; ".join(
            f"--{'-'.join(str(p) for p in e['loc']).replace('_', '-')}: {e['msg']} (got {e.get('input')!r})"
            for e in exc.errors()
        )
        raise SceneError(f"command line: {problems}") from None

    with _progress(quiet) as progress:
        image = render_scene(scene_model, threads=threads, aovs=bool(aov_paths), progress=progress, source=label)
    from .image import write_atomic

    image.save(output)
    for name, path in aov_paths.items():
        save_npy(path, image.aovs[name])
    if stats_path is not None:
        text = json.dumps(_json_safe(image.stats), indent=2) + "\n"
        write_atomic(stats_path, lambda fh: fh.write(text.encode()))
    if not quiet:
        s = image.stats
        typer.echo(
            f"{output}: {s['width']}x{s['height']} {s['mode']}, {s['rays'] / 1e6:.2f} Mrays in "
            f"{s['render_seconds']:.3f} s ({s['mrays_per_second']:.1f} Mrays/s), build {s['build_seconds']:.3f} s",
            err=True,
        )


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
        return None if self.quiet else self.update

    def update(self, done: int, total: int) -> None:
        import time

        if self.bar is None:
            if time.perf_counter() - self.start < 0.5 or done >= total:
                return
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

            self.bar = Progress(TextColumn("rendering"), BarColumn(), TextColumn("{task.percentage:>3.0f}%"),
                                TimeRemainingColumn(), transient=True, console=_stderr_console())
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


@app.command()
def scenes() -> None:
    """List the built-in scenes."""
    from .scene.builtin import DEFAULT_SCENE, builtin_description, builtin_names

    for name in builtin_names():
        mark = " (default)" if name == DEFAULT_SCENE else ""
        typer.echo(f"{name:<12} {builtin_description(name)}{mark}")


def main() -> None:  # pragma: no cover - console entry point
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
