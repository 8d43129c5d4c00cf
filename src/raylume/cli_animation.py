"""`raylume render SCENE -o out.mp4 | frames/f_%04d.png [--frames A:B]`: render an animation's
frames (in-process, or in parallel on a cluster) and write them as they arrive, in order."""

from __future__ import annotations

import json
import time
from pathlib import Path

import typer

from .animation import animation_of, parse_frames, render_animation
from .image import write_atomic
from .render_window import RenderInterrupted
from .scene.model import Scene
from .session import Session
from .settings import ResolvedSettings
from .video import VideoWriter, check_video_path, is_video, sequence_path


def render_animation_to(
    scene: Scene,
    label: str,
    output: Path,
    frames: str | None,
    settings: ResolvedSettings,
    *,
    cluster=None,
    quiet: bool = False,
    partial: bool = False,
    stats_path: Path | None = None,
    progress_bar=None,
    compile_notice=None,
    bit_depth: int = 8,
) -> None:
    """`progress_bar(quiet)` and `compile_notice(quiet, mode=...)`: the command's progress bar and
    compiling notice (cli.py), as a still render shows them."""
    animation = animation_of(scene, label)
    selected = parse_frames(frames, animation.frames) if frames is not None else range(animation.frames)
    table = settings.render
    writer = None
    if is_video(output):
        check_video_path(output, table.width, table.height)
    started = time.perf_counter()
    written: list[Path] = []
    done = 0
    compile_seconds = None  # the frames' (in-process frames report theirs; the first one compiles)
    work = {"rays": 0, "primary_rays": 0, "render_seconds": 0.0}  # the frames' summed (DESIGN.md's --stats)
    threads = None  # in-process frames' (a cluster's: its workers' threads, below)
    frame_spp: list[float] = []  # adaptive sampling: each frame's mean samples a pixel
    try:
        with progress_bar(quiet) as progress, compile_notice(quiet, mode=table.mode) as status:
            session = Session(scene, source=label, accelerate=table.mode != "raster", status=status)
            if is_video(output):
                writer = VideoWriter(output, table.width, table.height, animation.fps)
            frames_rendered = render_animation(
                session, selected, cluster=cluster, progress=progress, settings=settings, status=status
            )
            for k, image in frames_rendered:
                if writer is not None:
                    writer.write(image.to_uint8())
                else:
                    written.append(image.save(sequence_path(output, k), bit_depth=bit_depth))
                for key in work:
                    work[key] += image.stats.get(key, 0)
                threads = image.stats.get("threads", threads)
                if "compile_seconds" in image.stats:
                    compile_seconds = (compile_seconds or 0.0) + image.stats["compile_seconds"]
                if "adaptive" in image.stats:
                    frame_spp.append(image.stats["adaptive"]["mean_spp"])
                done += 1
        if writer is not None:
            writer.close()
    except (KeyboardInterrupt, RenderInterrupted):
        where = "nothing written"
        if writer is not None:
            kept = writer.abort(output.with_name(f"{output.stem}.partial{output.suffix}") if partial else None)
            where = f"saved {kept}" if kept else "no video written"
        elif written:
            where = f"{len(written)} frame files written"
        typer.echo(f"raylume: interrupted after {done} of {len(selected)} frames; {where}", err=True)
        raise typer.Exit(130) from None
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    seconds = time.perf_counter() - started
    cluster_stats = getattr(session, "last_cluster_stats", None)  # (on a cluster: its workers')
    if stats_path is not None:
        stats = {
            "frames": done,
            "first_frame": selected.start,
            "fps": animation.fps,
            "width": table.width,
            "height": table.height,
            "spp": table.spp,
            "mode": table.mode,
            "seconds": seconds,
            **session.compiled.stats,
            **work,
            "mrays_per_second": work["rays"] / work["render_seconds"] / 1e6 if work["render_seconds"] > 0 else 0.0,
        }
        stats["threads"] = cluster_stats["threads"] if cluster_stats else threads
        if compile_seconds is not None:
            stats["compile_seconds"] = compile_seconds
        if cluster_stats:  # the workers compile: the longest of theirs, as a still on a cluster says
            stats["cluster"] = cluster_stats
            stats["compile_seconds"] = stats.get("compile_seconds", 0.0) + cluster_stats.get("compile_seconds", 0.0)
        if frame_spp:
            stats["adaptive"] = {"mean_spp": sum(frame_spp) / len(frame_spp), "frames_mean_spp": frame_spp}
        text = json.dumps(stats, indent=2, default=float) + "\n"
        write_atomic(stats_path, lambda fh: fh.write(text.encode()))
    if not quiet:
        where = output if writer is not None else f"{output} ({len(written)} files)"
        typer.echo(
            f"{where}: {done} frames {table.width}x{table.height} {table.mode} in {seconds:.2f} s "
            f"({done / seconds:.2f} frames/s)"
            + (f"; on {cluster_stats['workers']} workers ({cluster_stats['tasks']} tasks)" if cluster_stats else "")
            + (f"; adaptive: {sum(frame_spp) / len(frame_spp):.1f} spp a pixel on average" if frame_spp else ""),
            err=True,
        )
