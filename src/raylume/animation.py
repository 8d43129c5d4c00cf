"""Camera animation: frames rendered from the `[animation]` keyframes (the camera of frame K:
scene/camera_path.py), in this process or on a cluster. A frame is a pure function of the
scene and K: frame K of a video is the still `--frame K`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING

from .errors import SceneError
from .scene.camera_path import TRACKS, animation_of, camera_at, interpolate  # noqa: F401 (raylume.animation's names too)
from .settings import OVERRIDES, ResolvedSettings, settings_of_call

if TYPE_CHECKING:
    from pathlib import Path

    from .image import Image
    from .scene.model import Scene
    from .session import Session


def parse_frames(text: str, frames: int) -> range:
    """`A:B` -> frames A..B-1 (either side may be left out: `:B`, `A:`), checked against the
    animation's frame count."""
    start, sep, stop = text.partition(":")
    try:
        a = int(start) if start.strip() else 0
        b = int(stop) if stop.strip() else frames
    except ValueError:
        a = b = -1
    if not sep or not 0 <= a < b <= frames:
        raise SceneError(
            f"--frames {text}: expected A:B with 0 <= A < B <= {frames} (frames A to B-1 of the {frames} frames)"
        )
    return range(a, b)


def render_animation(
    session: Session | Scene | str | Path,
    frames: Iterable[int] | None = None,
    *,
    cluster=None,
    progress: Callable[[int, int], None] | None = None,
    settings: ResolvedSettings | None = None,
    status: Callable[[str], None] | None = None,
    **arguments,
) -> Iterator[tuple[int, Image]]:
    """Render frames of the session's scene animation (default: all) and yield (frame, Image)
    in order (a scene instead of a session, named as raylume.render takes one: a session of its
    own). `settings` (raylume.settings.resolve_settings), or `arguments` as Session.render
    takes them (width, height, spp, mode, seed, ..., threads, crop), override the [render]
    table. With `cluster`, frames render in parallel on its workers (several frames in flight,
    each in tiles); frame K is bit-identical to the still of frame K. `progress(done, total)`
    counts frames in-process and tasks (tiles, passes) on a cluster. `status` hears each
    in-process frame's "compiling" and "rendering" (Session.render): the first frame's kernels
    compile (or load from the cache) there, and each frame's stats hold its `compile_seconds`."""
    unknown = sorted(set(arguments) - {*OVERRIDES, "threads", "crop"})
    if unknown:
        raise TypeError(f"render_animation: unexpected keyword arguments {', '.join(unknown)}")
    from .session import Session, primary_rays

    if not isinstance(session, Session):  # a scene, named as raylume.render takes one
        session = Session(session)
    scene, source = session.scene, session.source
    settings = settings_of_call(scene, arguments, settings, source)
    animation = animation_of(scene, source)
    frames = list(range(animation.frames) if frames is None else frames)
    cameras = [(k, camera_at(scene, k, source)) for k in frames]  # every camera checked before rendering
    if cluster is None:
        for done, (k, camera) in enumerate(cameras):
            if progress is not None:
                progress(done, len(cameras))
            yield k, session.render(camera, aovs=False, settings=settings, status=status)
        if progress is not None:
            progress(len(cameras), len(cameras))
        return
    from .cluster import FrameRenderer
    from .image import Image
    from .scene.checks import warn_about
    from .settings import samples_adaptively

    table = settings.render
    warn_about(scene, table.mode)  # as Session.render says them for the frames it renders
    adaptive = samples_adaptively(table, on_cluster=True, warn_if_ignored=True)
    denoising = table.denoise and table.mode == "path"
    renderer = FrameRenderer(
        cluster, session.compiled, settings, aovs=denoising, progress=progress, frames=len(cameras)
    )
    camera_of_frame = dict(cameras)
    for k, result in renderer.frames(cameras):
        rgb = result.rgb
        if denoising:  # here, as Session.render denoises a cluster's still: the same image
            albedo, normal = result.aovs["albedo"], result.aovs["normal"]
            rgb, _ = session._denoised(
                camera_of_frame[k], settings, rgb, albedo, normal, result.adaptive if adaptive else None
            )
        primary = primary_rays(table, table.width * table.height, result.adaptive if adaptive else None)
        stats = {"width": table.width, "height": table.height, "spp": table.spp, "mode": table.mode, "frame": k,
                 "rays": result.rays, "primary_rays": primary, "render_seconds": result.seconds}  # fmt: skip
        if adaptive:
            stats["adaptive"] = result.adaptive
        yield k, Image(rgb, {}, stats, table.encoding, exposure=table.exposure, tonemap=table.tonemap)
    session.last_cluster_stats = renderer.stats()
