"""`raylume view`: load the scene as `raylume render` does, bind the port, print the URL as
the first line on stdout, serve until Ctrl-C (exit status 130, as `raylume render`)."""

from __future__ import annotations

import os
import sys
import webbrowser
from typing import TYPE_CHECKING

from ..errors import RaylumeError

if TYPE_CHECKING:
    from ..scene.model import Scene
    from ..settings import ResolvedSettings


def run_view(
    scene_model: Scene,
    label: str,
    settings: ResolvedSettings,
    *,
    host: str,
    port: int,
    open_browser: bool,
) -> int:
    """Serve `scene_model` with the `settings` the command line resolved (size, spp, mode, threads)."""
    from ..session import Session
    from .renderer import MODES
    from .service import Viewer, warn_if_exposed

    if not 0 <= port <= 65535:
        raise RaylumeError(f"--port {port}: expected 0..65535 (0: a free port)")
    s = settings.render
    if s.mode not in MODES:
        raise RaylumeError(f"--mode {s.mode}: expected one of {', '.join(MODES)}")
    if s.denoise:
        from ..denoise import require_denoiser

        require_denoiser()  # a missing package fails now, not on the first frame
    viewer = Viewer(Session(scene_model, source=label), settings, host=host, port=port)
    what = f"{s.width}x{s.height} {s.mode}" + (", denoised" if s.denoise else "")

    def ready() -> None:  # serving, with Ctrl-C handled (Viewer.run)
        print(f"raylume view: {viewer.url}", flush=True)
        warn_if_exposed(host)
        print(f"raylume: serving {label}, {what}; Ctrl-C stops", file=sys.stderr, flush=True)
        if open_browser:
            webbrowser.open(viewer.url)

    code = viewer.run(ready)  # 130 after Ctrl-C, as `raylume render`
    print("raylume: view stopped", file=sys.stderr, flush=True)
    if viewer.renderer._thread is not None and viewer.renderer._thread.is_alive():
        # a pass (or a first kernel compilation) still runs: do not wait for it at exit
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code
