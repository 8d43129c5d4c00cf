"""`raylume view` end to end: a server subprocess and headless Chromium (Selenium with
Debian's chromium and chromium-driver, installed by .ci/run).

One server (160 x 120, trace mode, the seed scene) and one browser serve most of the module;
a second server shows the Cornell box in path mode with --denoise (96 x 72), a third a view
larger than the window (the seed, cast mode, 1200 x 900), both in a browser window of
800 x 600. The tests run in file order on one xdist worker (group "view"), and the last one
stops the first server with Ctrl-C."""

from __future__ import annotations

import base64
import io
import json
import math
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
from pathlib import Path

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
PW, PH = 96, 72  # the path-mode server's image
CORNELL = Path(__file__).resolve().parents[1] / "examples" / "cornell.toml"


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


def chromium(width: int, height: int):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(arg)
    options.add_argument(f"--window-size={width},{height}")
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


@pytest.fixture(scope="module")
def browser(server):
    driver = chromium(400, 300)
    driver.get(server.url)
    yield driver
    driver.quit()


def stopped(server: Server) -> None:
    if server.proc.poll() is None:
        server.proc.kill()
        server.proc.wait()


@pytest.fixture(scope="module")
def path_server():
    args = ["--mode", "path", "--denoise", "--width", str(PW), "--height", str(PH), "--port", "0", "--no-browser"]
    s = Server(str(CORNELL), *args)
    yield s
    stopped(s)


@pytest.fixture(scope="module")
def large_server():
    s = Server("seed", "--mode", "cast", "--width", "1200", "--height", "900", "--port", "0", "--no-browser")
    yield s
    stopped(s)


@pytest.fixture(scope="module")
def window_800_600():
    driver = chromium(800, 600)
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


LAYOUT = """
const box = (id) => { const b = document.getElementById(id).getBoundingClientRect();
                      return [b.left, b.top, b.right, b.bottom]; };
const root = document.documentElement, canvas = document.getElementById("view");
return {
  viewport: [root.clientWidth, root.clientHeight],
  scrolled: [root.scrollWidth, root.scrollHeight],
  pixels: [canvas.width, canvas.height],
  boxes: Object.fromEntries(
    ["view", "fps", "spp", "mrays", "mode", "denoise", "reset", "save"].map((id) => [id, box(id)])),
};
"""


def open_page(driver, server: Server) -> None:
    driver.get(server.url)
    wait_for(lambda: page_state(driver).get("drawn"), timeout=300, what="a first frame")


@pytest.mark.parametrize("size", ["small", "larger than the window"])
def test_an_800_x_600_window_shows_the_image_readouts_and_controls_without_scrolling(request, size, window_800_600):
    """All of it inside the viewport (getBoundingClientRect), nothing to scroll; the canvas at
    its own size when that fits, else shrunk to fit with its aspect ratio, never enlarged."""
    server = request.getfixturevalue("path_server" if size == "small" else "large_server")
    open_page(window_800_600, server)
    layout = window_800_600.execute_script(LAYOUT)
    width, height = layout["viewport"]
    assert layout["scrolled"][0] <= width and layout["scrolled"][1] <= height, layout
    for name, (left, top, right, bottom) in layout["boxes"].items():
        assert 0 <= left < right <= width and 0 <= top < bottom <= height, (name, layout)
    pixels = (PW, PH) if size == "small" else (1200, 900)
    assert tuple(layout["pixels"]) == pixels
    left, top, right, bottom = layout["boxes"]["view"]
    shown = (right - left, bottom - top)
    assert shown[0] <= pixels[0] and shown[1] <= pixels[1]  # never enlarged beyond its pixels
    if size == "small":
        assert shown == pytest.approx(pixels, abs=0.5)  # 1:1
    else:
        assert shown[0] / shown[1] == pytest.approx(pixels[0] / pixels[1], rel=0.01)
        assert right >= 0.6 * width or bottom >= 0.6 * height  # shrunk to fit, not to nothing


def test_path_mode_with_denoise_reports_it_in_stats(path_server):
    stats = path_server.stats()
    assert (stats["mode"], stats["denoise"], stats["integrator"]) == ("path", True, "path")
    assert (stats["width"], stats["height"]) == (PW, PH)


def orbit_position(angle: float) -> list[float]:
    """The Cornell box's camera (800 mm in front of look_at) turned `angle` radians about y."""
    return [278.0 + 800.0 * math.sin(angle), 273.0, -800.0 * math.cos(angle)]


def test_denoised_frames_keep_coming_while_the_camera_orbits(path_server, window_800_600):
    """POST /camera again and again, orbiting: the page draws frames of the moving camera
    (JPEG, filtered by SVGF) and /stats counts them."""
    open_page(window_800_600, path_server)
    before = path_server.stats()
    seen: set[int] = set()
    moves = 0
    end = time.monotonic() + 180  # a cold compile of the filter (about 10 s) comes first
    while len(seen) < 3 and time.monotonic() < end:
        body = json.dumps({"position": orbit_position(0.01 * moves)}).encode()
        assert path_server.get("/camera", method="POST", body=body)[0] == 200
        moves += 1
        last = page_state(window_800_600).get("last") or {}
        if last.get("format") == "jpeg" and last.get("denoised") and last["camera_version"] > before["camera_version"]:
            seen.add(last["frame"])
        time.sleep(0.03)
    assert len(seen) >= 3, "no denoised frames while the camera moved"
    after = path_server.stats()
    assert after["frames"] >= before["frames"] + 3
    assert after["camera_version"] == before["camera_version"] + moves
    # at rest: the accumulating image, denoised (OIDN), lossless; /frame.png is what the page shows
    wait_for(lambda: (page_state(window_800_600).get("last") or {}).get("format") == "png", what="a resting frame")
    assert page_state(window_800_600)["last"]["denoised"] is True
    wait_for(lambda: np.array_equal(canvas_pixels(window_800_600), path_server.frame_png()), what="the same image")


def test_the_denoise_checkbox_switches_denoising(path_server, window_800_600):
    open_page(window_800_600, path_server)
    box = window_800_600.find_element("id", "denoise")
    wait_for(lambda: box.is_selected(), what="the checkbox to show --denoise")

    def shown_denoised():
        return (page_state(window_800_600).get("last") or {}).get("denoised")

    box.click()
    wait_for(lambda: path_server.stats()["denoise"] is False, what="denoise off")
    wait_for(lambda: shown_denoised() is False, what="the image shown again, not denoised")
    assert not box.is_selected()
    box.click()
    wait_for(lambda: path_server.stats()["denoise"] is True, what="denoise on")
    wait_for(lambda: shown_denoised() is True, what="the image shown again, denoised")


def test_ctrl_c_stops_the_server_and_frees_the_port(server, browser):
    server.proc.send_signal(signal.SIGINT)
    started = time.monotonic()
    code = server.proc.wait(timeout=10)
    assert code == 130  # as `raylume render` exits on Ctrl-C
    assert time.monotonic() - started < 2.0
    with socket.socket() as s:
        # free again: a server may listen on it (SO_REUSEADDR, as servers do, passes over the closed
        # connections in TIME_WAIT but not over a listening socket)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", server.port))
        s.listen()
