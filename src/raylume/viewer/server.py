"""The viewer's web server (Tornado, asyncio): one page, its script, /stats, /frame.png,
POST /camera and a WebSocket that pushes frames and takes gestures.

Tornado rather than the `websockets` package: its HTTP side parses only GET requests, and
POST /camera is part of the contract; Tornado is already installed with Dask's `distributed`.

Security (DESIGN.md section 6): every request must carry the session's random token (403
otherwise, compared in constant time); WebSocket upgrades whose Origin is not the page's own
host are refused (Tornado's same-origin check); the only files served are the two named in
PAGES, read from the package, so no request can name a path to read.
"""

from __future__ import annotations

import asyncio
import errno
import hmac
import json
import secrets
import socket
from importlib import resources

import tornado.httpserver
import tornado.log
import tornado.netutil
import tornado.web
import tornado.websocket

from ..errors import RaylumeError
from .frames import Frame
from .renderer import Renderer

PAGES = {"/": ("index.html", "text/html; charset=utf-8"), "/view.js": ("view.js", "text/javascript; charset=utf-8")}
LOOPBACK = ("127.0.0.1", "localhost", "::1")
FIRST_FRAME_TIMEOUT = 300.0  # /frame.png waits this long for the first frame (a cold kernel compile)


def bind(host: str, port: int) -> list[socket.socket]:
    """Listening sockets for host:port (port 0: a free one); a port in use is a RaylumeError
    naming it."""
    try:
        return tornado.netutil.bind_sockets(port, host, reuse_port=False)
    except socket.gaierror as exc:  # (an OSError too: caught first)
        raise RaylumeError(f"--host {host}: not an address of this machine ({exc.strerror})") from None
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise RaylumeError(
                f"port {port} on {host} is in use (another raylume view?); choose another with --port P, "
                "or --port 0 for a free one"
            ) from None
        if exc.errno in (errno.EADDRNOTAVAIL, errno.EACCES):
            raise RaylumeError(f"cannot listen on {host}:{port} ({exc.strerror}); check --host and --port") from None
        raise


class ViewServer:
    """Serves `renderer`'s frames on `sockets`. Call start() inside a running asyncio loop."""

    def __init__(self, renderer: Renderer, sockets: list[socket.socket], token: str | None = None):
        self.renderer = renderer
        self.sockets = sockets
        self.token = token or secrets.token_urlsafe(18)
        self.clients: set[FrameSocket] = set()
        self.loop: asyncio.AbstractEventLoop | None = None
        self.http: tornado.httpserver.HTTPServer | None = None
        host, port = sockets[0].getsockname()[:2]
        self.port = port
        self.host = host

    def url(self, host: str | None = None) -> str:
        host = host or self.host
        if ":" in host:  # an IPv6 literal
            host = f"[{host}]"
        return f"http://{host}:{self.port}/?token={self.token}"

    def start(self) -> None:
        self.loop = asyncio.get_running_loop()
        args = {"server": self}
        app = tornado.web.Application(
            [
                (r"/", PageHandler, args),
                (r"/view\.js", PageHandler, args),
                (r"/stats", StatsHandler, args),
                (r"/frame\.png", FramePngHandler, args),
                (r"/camera", CameraHandler, args),
                (r"/ws", FrameSocket, args),
            ],
            default_handler_class=NotFoundHandler,
            default_handler_args=args,
            websocket_max_message_size=1 << 16,
            log_function=_log_request,
        )
        self.http = tornado.httpserver.HTTPServer(app, max_body_size=1 << 16)
        self.http.add_sockets(self.sockets)
        self.renderer.on_frame = self.frame_ready

    def frame_ready(self, frame: Frame) -> None:
        """Called on the render thread: hand the frame to the loop's thread."""
        if self.loop is not None and not self.loop.is_closed():
            try:
                self.loop.call_soon_threadsafe(self.broadcast, frame)
            except RuntimeError:  # the loop closed meanwhile
                pass

    def broadcast(self, frame: Frame) -> None:
        extra = self.frame_extra()
        for client in list(self.clients):
            client.offer(frame, extra)

    def frame_extra(self) -> dict:
        """What a frame's header carries besides the frame itself: the rates, the view's size and
        whether path mode's frames are denoised (the page's checkbox follows it)."""
        stats = self.renderer.stats()
        return {
            "fps": stats["fps"],
            "denoise": stats["denoise"],
            "mrays_per_second": stats["mrays_per_second"],
            "status": stats["status"],
            "full_width": self.renderer.width,
            "full_height": self.renderer.height,
        }

    async def stop(self) -> None:
        if self.http is not None:
            self.http.stop()  # closes the listening sockets: the port is free again
        for client in list(self.clients):
            client.close()
        if self.http is not None:
            try:
                await asyncio.wait_for(self.http.close_all_connections(), 0.5)
            except TimeoutError:
                pass


def _log_request(handler: tornado.web.RequestHandler) -> None:
    """Tornado logs every request with its URL, which holds the token: log server errors only,
    by path."""
    if handler.get_status() >= 500:
        tornado.log.access_log.error("%d %s %s", handler.get_status(), handler.request.method, handler.request.path)


class _Base(tornado.web.RequestHandler):
    def initialize(self, server: ViewServer) -> None:
        self.server = server

    def prepare(self) -> None:
        token = self.get_query_argument("token", "")
        if not hmac.compare_digest(token.encode(), self.server.token.encode()):
            raise tornado.web.HTTPError(403)

    def set_default_headers(self) -> None:
        self.set_header("Cache-Control", "no-store")
        self.set_header("X-Content-Type-Options", "nosniff")
        self.set_header("Referrer-Policy", "no-referrer")  # the token is in the URL

    def write_error(self, status_code: int, **kwargs) -> None:
        reason = kwargs.get("reason") or self._reason
        self.set_header("Content-Type", "text/plain; charset=utf-8")
        self.finish(f"{status_code} {reason}\n")

    def json(self, value: dict, status: int = 200) -> None:
        self.set_status(status)
        self.set_header("Content-Type", "application/json")
        self.finish(json.dumps(value))

    def log_exception(self, typ, value, tb) -> None:
        """Tornado's own names the request's URL, which holds the token: the path alone."""
        if isinstance(value, tornado.web.HTTPError):
            return
        tornado.log.app_log.error(
            "uncaught exception %s %s", self.request.method, self.request.path, exc_info=(typ, value, tb)
        )


class NotFoundHandler(_Base):
    def prepare(self) -> None:
        super().prepare()
        raise tornado.web.HTTPError(404)


class PageHandler(_Base):
    def get(self) -> None:
        name, kind = PAGES[self.request.path]
        self.set_header("Content-Type", kind)
        self.finish(resources.files(__package__).joinpath("static", name).read_bytes())


class StatsHandler(_Base):
    def get(self) -> None:
        self.json(self.server.renderer.stats())


class FramePngHandler(_Base):
    async def get(self) -> None:
        renderer = self.server.renderer
        waited = 0.0
        while renderer.latest is None and waited < FIRST_FRAME_TIMEOUT:
            await asyncio.sleep(0.05)
            waited += 0.05
        frame = renderer.latest
        if frame is None:
            raise tornado.web.HTTPError(503, reason="no frame rendered yet")
        self.set_header("Content-Type", "image/png")
        self.set_header("X-Raylume-Spp", str(frame.spp))
        self.set_header("X-Raylume-Camera-Version", str(frame.camera_version))
        self.finish(await asyncio.to_thread(frame.png))


class CameraHandler(_Base):
    def post(self) -> None:
        try:
            updates = json.loads(self.request.body or b"{}")
            if not isinstance(updates, dict):
                raise ValueError("expected a JSON object")
        except RecursionError:
            self.json({"error": "POST /camera: the body is nested too deeply"}, 400)
            return
        except ValueError as exc:
            self.json({"error": f"POST /camera: the body is not a JSON object ({exc})"}, 400)
            return
        try:
            version = self.server.renderer.set_camera(updates)
        except RaylumeError as exc:
            self.json({"error": str(exc)}, 400)
            return
        except (RecursionError, OverflowError, ValueError, TypeError) as exc:  # past the model's own checks
            self.json({"error": f"POST /camera: {exc}"}, 400)
            return
        self.json({"camera_version": version, "camera": self.server.renderer.stats()["camera"]})


# The largest gesture a message may carry (pixels dragged, wheel units): far past any drag, and
# small enough that the camera's arithmetic stays finite
GESTURE_LIMIT = 1e6


def _shown(value) -> str:
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _gesture_number(m: dict, kind: str, key: str) -> float:
    """m[key] as a gesture's size: a finite number within GESTURE_LIMIT, else a ValueError
    naming the message type and the key."""
    value = m.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not abs(value) <= GESTURE_LIMIT:
        raise ValueError(
            f"{kind}: {key!r} must be a number from -{GESTURE_LIMIT:g} to {GESTURE_LIMIT:g}, got {_shown(value)}"
        )
    return float(value)


class FrameSocket(tornado.websocket.WebSocketHandler):
    """One open page. Frames are offered to it as they come; while one is still being written
    to a slow client, only the newest waiting frame is kept (older ones are dropped)."""

    def initialize(self, server: ViewServer) -> None:
        self.server = server
        self.sending = False
        self.waiting: tuple[Frame, dict] | None = None

    def prepare(self) -> None:
        _Base.prepare(self)

    def open(self) -> None:
        self.server.clients.add(self)
        self.server.renderer.add_watcher(1)
        frame = self.server.renderer.latest
        if frame is not None:
            self.offer(frame, self.server.frame_extra())

    def on_close(self) -> None:
        if self in self.server.clients:
            self.server.clients.discard(self)
            self.server.renderer.add_watcher(-1)

    def on_message(self, message) -> None:
        """Gestures and commands from the page, as JSON: {"type": "orbit" | "pan", "dx", "dy"},
        {"type": "dolly", "delta"}, {"type": "reset"}, {"type": "mode", "mode"},
        {"type": "denoise", "on": true | false}."""
        renderer = self.server.renderer
        try:
            try:
                m = json.loads(message)
            except RecursionError:
                raise ValueError("the message is nested too deeply") from None
            if not isinstance(m, dict):
                raise ValueError("a message is a JSON object with a 'type'")
            kind = m.get("type")
            if kind in ("orbit", "pan"):
                renderer.gesture(kind, dx=_gesture_number(m, kind, "dx"), dy=_gesture_number(m, kind, "dy"))
            elif kind == "dolly":
                renderer.gesture("dolly", delta=_gesture_number(m, kind, "delta"))
            elif kind == "reset":
                renderer.reset_camera()
            elif kind == "mode":
                if not isinstance(m.get("mode"), str):
                    raise ValueError(f"mode: 'mode' must be a mode's name, got {_shown(m.get('mode'))}")
                renderer.set_mode(m["mode"])
            elif kind == "denoise":
                if not isinstance(m.get("on"), bool):
                    raise ValueError(f"denoise: 'on' must be true or false, got {_shown(m.get('on'))}")
                renderer.set_denoise(m["on"])
            else:
                raise ValueError(
                    f"unknown message type {_shown(kind)}; expected orbit, pan, dolly, reset, mode or denoise"
                )
        except (ValueError, OverflowError, RaylumeError) as exc:
            self.write_message(json.dumps({"error": str(exc)}))

    def offer(self, frame: Frame, extra: dict) -> None:
        if self.sending:
            self.waiting = (frame, extra)
            return
        self._send(frame, extra)

    def _send(self, frame: Frame, extra: dict) -> None:
        try:
            future = self.write_message(frame.message(extra), binary=True)
        except tornado.websocket.WebSocketClosedError:
            return
        self.sending = True
        future.add_done_callback(self._sent)

    def _sent(self, future) -> None:
        self.sending = False
        if future.exception() is not None:
            return
        if self.waiting is not None:
            frame, extra = self.waiting
            self.waiting = None
            self._send(frame, extra)
