"""The live view (`raylume view`, `raylume.view(scene)`): a local web page that shows a scene
rendering progressively and lets the mouse move the camera.

    camera_control.py  orbit / pan / dolly math
    renderer.py        the render thread: passes through a Session, films, frames
    frames.py          a frame's 8-bit pixels, JPEG/PNG encodings and WebSocket message
    server.py          the Tornado app: page, /stats, /frame.png, POST /camera, /ws; the token
    service.py         binding, serving in the foreground or on a background thread, shutdown
    static/            index.html and view.js (plain, no build step)
"""

from __future__ import annotations

import atexit
import os

from ..scene.model import Scene

_RUNNING: list = []


class ViewURL(str):
    """The URL of a running view (a str), with `stop()` and the `viewer` behind it."""

    viewer: object

    def stop(self) -> None:
        self.viewer.stop()
        if self.viewer in _RUNNING:
            _RUNNING.remove(self.viewer)


def view(
    scene: Scene | str | os.PathLike | None = None,
    *,
    width: int | None = None,
    height: int | None = None,
    mode: str | None = None,
    integrator: str | None = None,
    spp: int | None = None,
    denoise: bool | None = None,
    tonemap: str | None = None,
    host: str = "127.0.0.1",
    port: int = 0,
    threads: int | None = None,
    show: bool | None = None,
    defines: dict[str, str] | None = None,
) -> ViewURL:
    """Serve a live view of `scene` (a Scene, a scene, glTF or mesh file, a built-in name, or
    None for `seed`) in the background and return its URL (with the token). In Jupyter (or when
    `show`) the page is also shown inline in an iframe. Port 0 (the default here) picks a free
    port, so several views can run at once; `url.stop()` ends one. `denoise`: path mode's
    frames shown denoised (SVGF while the camera moves, OIDN at rest), as `raylume view --denoise`;
    `integrator`: path mode's, "path" or "bdpt" (as `raylume view --integrator`); `tonemap`: the
    frames' tone mapping, none | reinhard | aces | agx | neutral (as --tonemap). `defines`: a
    Mitsuba scene's $parameters (as --define)."""
    arguments = dict(locals())  # the call's arguments, before any other name is bound
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        # (the socket took 70000 as 4464, and -1 as a bad host)
        raise ValueError(f"port={port!r}: expected 0..65535 (0: a free port)")
    from ..scene.open import open_scene
    from ..session import Session
    from ..settings import overrides_of, resolve_settings
    from .service import Viewer, warn_if_exposed

    scene, source = open_scene(scene, width=width, height=height, defines=defines)
    settings = resolve_settings(scene, overrides_of(arguments), threads=threads, source=source)
    if settings.render.denoise:
        from ..denoise import require_denoiser

        require_denoiser()
    warn_if_exposed(host)
    viewer = Viewer(Session(scene, source=source), settings, host=host, port=port)
    viewer.start()
    _RUNNING.append(viewer)
    url = ViewURL(viewer.url)
    url.viewer = viewer
    if show or (show is None and _in_notebook()):
        try:
            from IPython.display import IFrame, display
        except ImportError:  # not in IPython: there is nothing to show the page in
            return url
        display(IFrame(url, width=settings.render.width + 40, height=settings.render.height + 100))
    return url


def _in_notebook() -> bool:
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and type(shell).__name__ == "ZMQInteractiveShell"


@atexit.register
def _stop_all() -> None:
    for viewer in list(_RUNNING):
        viewer.stop()
