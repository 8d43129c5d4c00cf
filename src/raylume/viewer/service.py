"""A running viewer: the render thread and the web server, either in the foreground (the
`raylume view` command, until Ctrl-C) or on a background thread (`raylume.view(scene)`)."""

from __future__ import annotations

import asyncio
import ipaddress
import signal
import sys
import threading
from collections.abc import Callable

from ..session import Session
from ..settings import ResolvedSettings
from .renderer import Renderer
from .server import LOOPBACK, ViewServer, bind

STOP_SECONDS = 1.0  # how long shutting down may wait for the pass in flight


def is_loopback(host: str) -> bool:
    if host in LOOPBACK:
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class Viewer:
    """Binds host:port at once (a port in use is a RaylumeError naming it), then serves
    `session`'s scene with `settings` (size, spp, mode, threads; default: its [render] table's) when run."""

    def __init__(
        self, session: Session, settings: ResolvedSettings | None = None, *, host: str = "127.0.0.1", port: int = 8765
    ):
        self.sockets = bind(host, port)
        self.renderer = Renderer(session, settings)
        self.server = ViewServer(self.renderer, self.sockets)
        self.url = self.server.url(host)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread: threading.Thread | None = None
        self.stopped_by: int | None = None  # the signal that stopped run(): SIGINT (Ctrl-C) or SIGTERM

    async def serve(
        self, started: threading.Event | None = None, signals: bool = False, ready: Callable[[], None] | None = None
    ) -> None:
        """Serve until stop() (or SIGINT/SIGTERM when `signals`), then close the port and stop
        the render thread. `ready` is called once the port serves and the signals are handled."""
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        if signals:
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._loop.add_signal_handler(sig, self._stopped_by, sig)
        self.server.start()
        self.renderer.start()
        if started is not None:
            started.set()
        if ready is not None:
            ready()
        try:
            await self._stop.wait()
        finally:
            await self.server.stop()
            # here, not in the loop's executor: a background view still running at the
            # interpreter's exit is stopped (atexit) after that executor has shut down, and
            # asyncio.to_thread raised there (a traceback on every such exit). Nothing else
            # waits for this loop once the server has stopped.
            self.renderer.stop(STOP_SECONDS)

    def _stopped_by(self, sig: int) -> None:
        self.stopped_by = sig
        self._stop.set()

    def run(self, ready: Callable[[], None] | None = None) -> int:
        """Serve in the foreground until Ctrl-C or SIGTERM; returns the exit status that signal
        means, as `raylume render` exits on Ctrl-C: 128 + its number (130 for Ctrl-C). `ready`
        is called once Ctrl-C is handled by the server (where `raylume view` prints its URL: a
        Ctrl-C right after it then stops the server, never an import or start-up half done)."""
        asyncio.run(self.serve(signals=True, ready=ready))
        return 0 if self.stopped_by is None else 128 + int(self.stopped_by)

    def start(self) -> None:
        """Serve on a background thread (daemon: it never keeps the interpreter alive)."""
        started = threading.Event()
        self._thread = threading.Thread(
            target=lambda: asyncio.run(self.serve(started)), name="raylume-view-server", daemon=True
        )
        self._thread.start()
        started.wait(10)

    def stop(self) -> None:
        """Stop a background viewer: the port is free and the render thread ended when this returns."""
        if self._loop is not None and self._stop is not None and not self._loop.is_closed():
            try:
                self._loop.call_soon_threadsafe(self._stop.set)
            except RuntimeError:
                pass
        if self._thread is not None:
            self._thread.join(STOP_SECONDS + 1.0)


def warn_if_exposed(host: str) -> None:
    if not is_loopback(host):
        print(
            f"raylume: warning: --host {host}: the view is reachable from other machines; anyone with the URL "
            "(its token) can watch the scene and move the camera",
            file=sys.stderr,
        )
