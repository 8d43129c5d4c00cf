"""`raylume view` end to end: a server subprocess and headless Chromium (Selenium with
Debian's chromium and chromium-driver, installed by .ci/run).

One server (160 x 120, trace mode, the seed scene) and one browser serve the whole module;
the tests run in file order on one xdist worker (group "view"), and the last one stops the
server with Ctrl-C."""

from __future__ import annotations

import base64
import io
import json
import os
import select
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
from PIL import Image as PILImage
from test_cli import raylume

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
try:
    import selenium  # noqa: F401
except ImportError:
    selenium = None

pytestmark = [
    pytest.mark.xdist_group("view"),
    pytest.mark.skipif(
        CHROMIUM is None or CHROMEDRIVER is None or selenium is None,
        reason="needs Debian's chromium and chromium-driver and the selenium package (.ci/run installs them)",
    ),
]

W, H = 160, 120


class Server:
    def __init__(self, *args: str):
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "raylume.cli", "view", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        ready, _, _ = select.select([self.proc.stdout], [], [], 60)
        assert ready, "raylume view printed no URL within 60 s"
        self.first_line = self.proc.stdout.readline().rstrip("\n")
        prefix = "raylume view: "
        assert self.first_line.startswith(prefix), (self.first_line, self.proc.stderr.read())
        self.url = self.first_line[len(prefix) :]
        self.base, _, self.token = self.url.partition("/?token=")
        self.port = int(self.base.rsplit(":", 1)[1])

    def get(self, path: str, token: bool = True, method: str = "GET", body: bytes | None = None):
        sep = "&" if "?" in path else "?"
        url = self.base + path + (f"{sep}token={self.token}" if token else "")
        request = urllib.request.Request(url, data=body, method=method)
        try:
            with urllib.request.urlopen(request, timeout=30) as response:
                return response.status, response.read()
        except urllib.error.HTTPError as exc:
            return exc.code, exc.read()

    def stats(self) -> dict:
        status, body = self.get("/stats")
        assert status == 200
        return json.loads(body)

    def frame_png(self) -> np.ndarray:
        status, body = self.get("/frame.png")
        assert status == 200
        return np.asarray(PILImage.open(io.BytesIO(body)).convert("RGB"))


@pytest.fixture(scope="module")
def server():
    s = Server("seed", "--mode", "trace", "--width", str(W), "--height", str(H), "--port", "0", "--no-browser")
    yield s
    if s.proc.poll() is None:
        s.proc.kill()
        s.proc.wait()


@pytest.fixture(scope="module")
def browser(server):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=400,300"):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.get(server.url)
    yield driver
    driver.quit()


def wait_for(predicate, timeout: float = 60.0, what: str = "condition"):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def page_state(browser) -> dict:
    return browser.execute_script("return window.raylumeView || null;") or {}


def wait_at_rest(server, browser) -> dict:
    """Wait until the page shows the converged, lossless frame of the server's current camera."""

    def rested():
        last = page_state(browser).get("last")
        stats = server.stats()
        if last and last["converged"] and last["format"] == "png" and last["camera_version"] == stats["camera_version"]:
            return stats
        return None

    return wait_for(rested, timeout=300, what="the view to rest")  # a first, cold kernel compile takes long


def canvas_pixels(browser) -> np.ndarray:
    url = browser.execute_script("return document.getElementById('view').toDataURL('image/png');")
    data = base64.b64decode(url.split(",", 1)[1])
    return np.asarray(PILImage.open(io.BytesIO(data)).convert("RGB"))


def render_png(camera: dict, tmp_path) -> np.ndarray:
    sets = [f"camera.{k}={json.dumps(v)}" for k, v in camera.items()]
    args = ["render", "seed", "--mode", "trace", "--width", W, "--height", H, "-o", tmp_path / "r.png", "--quiet"]
    for s in sets:
        args += ["--set", s]
    result = raylume(*args, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    return np.asarray(PILImage.open(tmp_path / "r.png").convert("RGB"))


def drag(browser, kind: str = "orbit", steps: int = 6, step: int = 8) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys

    canvas = browser.find_element("id", "view")
    chain = ActionChains(browser, duration=20)
    if kind == "pan":
        chain.key_down(Keys.SHIFT)
    chain.move_to_element(canvas).click_and_hold()
    for _ in range(steps):
        chain.move_by_offset(step, step // 2)
    chain.release()
    if kind == "pan":
        chain.key_up(Keys.SHIFT)
    chain.perform()


def test_first_line_is_the_url_with_its_token(server):
    assert server.first_line.startswith("raylume view: http://127.0.0.1:")
    assert len(server.token) >= 16


def test_canvas_shows_the_scene_as_frame_png(server, browser):
    assert browser.find_element("id", "view").tag_name == "canvas"
    stats = wait_at_rest(server, browser)
    assert (stats["width"], stats["height"], stats["mode"], stats["spp"]) == (W, H, "trace", 1)
    shown = canvas_pixels(browser)
    assert shown.shape == (H, W, 3)
    np.testing.assert_array_equal(shown, server.frame_png())
    assert shown.max() > 0


def test_drag_orbits_the_camera_and_rests_on_raylume_renders_image(server, browser, tmp_path):
    before = server.stats()
    image_before = canvas_pixels(browser)
    drag(browser)
    moved = wait_for(lambda: (s := server.stats())["camera_version"] > before["camera_version"] and s, what="a move")
    assert moved["camera"]["position"] != before["camera"]["position"]
    assert moved["camera"]["look_at"] == before["camera"]["look_at"]  # an orbit keeps the target
    assert moved["fps"] > 0
    stats = wait_at_rest(server, browser)
    shown = canvas_pixels(browser)
    assert not np.array_equal(shown, image_before)
    np.testing.assert_array_equal(shown, server.frame_png())
    # at rest in trace mode: pixel for pixel what `raylume render` makes of the same camera
    np.testing.assert_array_equal(shown, render_png(stats["camera"], tmp_path))


def test_shift_drag_pans_and_reset_returns_home(server, browser):
    home = {"position": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, 1.0], "up": [0.0, 1.0, 0.0], "fov": 53.13}
    before = server.stats()
    drag(browser, "pan", steps=3)
    panned = wait_for(lambda: (s := server.stats())["camera_version"] > before["camera_version"] and s, what="a pan")
    assert panned["camera"]["look_at"] != before["camera"]["look_at"]
    wait_at_rest(server, browser)
    browser.find_element("id", "reset").click()
    wait_for(lambda: server.stats()["camera"] == home, what="the reset camera")


def test_post_camera_moves_the_camera(server, browser):
    version = server.stats()["camera_version"]
    body = json.dumps({"position": [0.5, 0.25, -0.5], "fov": 45}).encode()
    status, answer = server.get("/camera", method="POST", body=body)
    assert status == 200, answer
    stats = server.stats()
    assert stats["camera_version"] == version + 1
    assert stats["camera"]["position"] == [0.5, 0.25, -0.5] and stats["camera"]["fov"] == 45
    wait_at_rest(server, browser)
    status, answer = server.get("/camera", method="POST", body=b'{"fov": 500}')
    assert status == 400 and b"fov" in answer
    status, answer = server.get("/camera", method="POST", body=b'{"zoom": 2}')
    assert status == 400 and b"zoom" in answer


def test_a_second_tab_sees_the_same_view(server, browser):
    first = browser.current_window_handle
    browser.switch_to.new_window("tab")
    try:
        browser.get(server.url)
        wait_at_rest(server, browser)
        np.testing.assert_array_equal(canvas_pixels(browser), server.frame_png())
        assert server.stats()["watchers"] == 2
    finally:
        browser.close()
        browser.switch_to.window(first)
    wait_for(lambda: server.stats()["watchers"] == 1, what="the closed tab to leave")


def test_the_page_switches_the_mode(server, browser):
    from selenium.webdriver.support.ui import Select

    Select(browser.find_element("id", "mode")).select_by_value("cast")
    wait_for(lambda: server.stats()["mode"] == "cast", what="cast mode")
    wait_for(lambda: (page_state(browser).get("last") or {}).get("mode") == "cast", timeout=300, what="a cast frame")
    wait_at_rest(server, browser)
    np.testing.assert_array_equal(canvas_pixels(browser), server.frame_png())
    Select(browser.find_element("id", "mode")).select_by_value("trace")
    wait_for(lambda: server.stats()["mode"] == "trace", what="trace mode")


def test_every_request_needs_the_token(server):
    for path in ("/", "/view.js", "/stats", "/frame.png", "/ws", "/nothing"):
        assert server.get(path, token=False)[0] == 403, path
        assert server.get(path + "?token=wrong", token=False)[0] == 403, path
    assert server.get("/camera", token=False, method="POST", body=b'{"fov": 40}')[0] == 403
    assert server.stats()["camera"]["fov"] != 40
    # no path names a file: only the page and its script are served
    for path in ("/static/view.js", "/../pyproject.toml", "/%2e%2e/%2e%2e/etc/passwd", "/index.html"):
        assert server.get(path)[0] == 404, path
    status, page = server.get("/")
    assert status == 200 and b'id="view"' in page


def test_websocket_from_another_origin_is_refused(server):
    import asyncio

    from tornado.httpclient import HTTPClientError, HTTPRequest
    from tornado.websocket import websocket_connect

    ws_url = server.base.replace("http://", "ws://") + f"/ws?token={server.token}"

    async def connect(origin: str):
        request = HTTPRequest(ws_url, headers={"Origin": origin}, connect_timeout=10)
        conn = await websocket_connect(request)
        message = await asyncio.wait_for(conn.read_message(), 30)  # the frame now shown
        conn.close()
        return message

    with pytest.raises(HTTPClientError) as refused:
        asyncio.run(connect("http://evil.example"))
    assert refused.value.code == 403
    message = asyncio.run(connect(server.base))
    assert isinstance(message, bytes) and b'"format"' in message[:400]


def test_a_port_in_use_is_a_clear_error(server, tmp_path):
    result = raylume("view", "--port", server.port, "--no-browser", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert f"port {server.port}" in result.stderr and "Traceback" not in result.stderr
    assert result.stdout == ""


def test_ctrl_c_stops_the_server_and_frees_the_port(server, browser):
    server.proc.send_signal(signal.SIGINT)
    started = time.monotonic()
    code = server.proc.wait(timeout=10)
    assert code in (0, 130)
    assert time.monotonic() - started < 2.0
    with socket.socket() as s:
        # free again: a server may listen on it (SO_REUSEADDR, as servers do, passes over the closed
        # connections in TIME_WAIT but not over a listening socket)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", server.port))
        s.listen()
