"""One render call: compile the scene, render it once (a Session used once)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from distributed import Client

    from .image import Image
    from .render_window import AOV_NAMES, RENDER_AOVS, RenderInterrupted, allocate_aovs
    from .scene.open import SceneLike
    from .session import check_memory, estimate_bytes
    from .settings import ResolvedSettings

__all__ = ["AOV_NAMES", "RENDER_AOVS", "RenderInterrupted", "allocate_aovs", "check_memory", "estimate_bytes", "render"]

# raylume/__init__.py imports this module at once (its `render` function must shadow the module
# of the same name), so it stays light: what it needs is imported on use, and the names it
# re-exports are loaded on first access.
_FROM_RENDER_WINDOW = {"AOV_NAMES", "RENDER_AOVS", "RenderInterrupted", "allocate_aovs"}
_FROM_SESSION = {"check_memory", "estimate_bytes"}


def __getattr__(name: str):
    if name in _FROM_RENDER_WINDOW:
        from . import render_window

        return getattr(render_window, name)
    if name in _FROM_SESSION:
        from . import session

        return getattr(session, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def render(
    scene: SceneLike = None,
    *,
    width: int | None = None,
    height: int | None = None,
    spp: int | None = None,
    mode: str | None = None,
    integrator: str | None = None,
    max_depth: int | None = None,
    seed: int | None = None,
    filter: str | None = None,
    exposure: float | None = None,
    tonemap: str | None = None,
    denoise: bool | None = None,
    noise_threshold: float | None = None,
    min_spp: int | None = None,
    time_limit: float | None = None,
    threads: int | None = None,
    aovs: bool = True,
    progress: Callable[[int, int], None] | None = None,
    source: str = "<scene>",
    crop: tuple[int, int, int, int] | None = None,
    status: Callable[[str], None] | None = None,
    cluster: str | Client | None = None,
    settings: ResolvedSettings | None = None,
    defines: dict[str, str] | None = None,
) -> Image:
    """Render `scene` (arguments override its [render] table): a Scene, a path to a scene,
    glTF or mesh file (a mesh is framed and lit), or a built-in scene's name, as the command
    line's SCENE (None: the built-in `seed`). Returns an Image with linear
    float32 RGB, the AOVs (depth, normal, object, prim, albedo, instance) when `aovs` is true, and the
    stats dictionary. To render one scene several times (other cameras, sizes, modes), use a
    Session: it compiles once. `crop` = (x0, x1, y0, y1) renders only columns x0..x1-1 and
    rows y0..y1-1: the image is that window, equal to the same window of the full render.
    `status` is called with "compiling" before the kernels' first call and "rendering" after
    it (see Session.render), and with "compiling the BVH builder" and "building" around the
    first build on a machine (see Session). `cluster`: a Dask scheduler's address, `local`, `local:N` or a
    `distributed.Client`: render in tiles on its workers, bit-identical (raylume.cluster).
    `noise_threshold`, `min_spp`, `time_limit`: adaptive sampling, tiles that stop taking
    samples once their noise is below the threshold or the time is spent (see Session.render).
    `settings`: settings already resolved (raylume.settings.resolve_settings), in place of
    width ... time_limit, threads and crop. `defines`: a Mitsuba scene's $parameters (as --define)."""
    arguments = dict(locals())  # the call's arguments, before any other name is bound
    from .scene.open import open_scene
    from .session import Session
    from .settings import settings_of_call

    size = (width, height) if settings is None else (settings.render.width, settings.render.height)
    scene, label = open_scene(scene, width=size[0], height=size[1], defines=defines)  # a mesh: framed for that size
    source = label if source == "<scene>" else source
    settings = settings_of_call(scene, arguments, settings, source)  # fail before compiling
    session = Session(scene, source=source, accelerate=settings.render.mode != "raster", status=status)
    return session.render(aovs=aovs, progress=progress, status=status, cluster=cluster, settings=settings)
