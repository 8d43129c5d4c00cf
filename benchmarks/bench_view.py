"""`raylume view` in headless Chromium: frames per second drawn by the page for the seed scene in
trace mode while the camera orbits (a scripted drag, real pointer input through chromedriver)
and at rest (progressive passes of a 64-spp film), and the latency from a gesture sent by the
page to the first frame of the new camera drawn on its canvas. The camera looks at (0, 0, 3.5)
instead of the seed's (0, 0, 1): the same first image, and the orbit goes round the spheres.

Then path mode: the Cornell box (examples/cornell.toml) at 320 x 240 orbiting, with and without
--denoise (SVGF on every moving frame), each in a server and browser of its own, the runs
alternating (off, on, off, on, ...); medians.

python benchmarks/bench_view.py [--sizes 320x240,640x480] [--seconds 6] [--threads T]
                                [--screenshot docs/images/view.png] [--only trace|path] [--runs 3]

Needs Debian's chromium and chromium-driver and the selenium package (the dev extra).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import select
import shutil
import statistics
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

from common import machine, run_main, table

# The seed's camera looks at (0, 0, 1); the same view direction with look_at among the spheres
# gives the same first image and an orbit around them.
LOOK_AT = "[0, 0, 3.5]"
STEP_MS = int(os.environ.get("STEP_MS", "16"))  # pointer moves every STEP_MS milliseconds
GESTURE_LATENCY_JS = """
const done = arguments[arguments.length - 1];
const view = window.raylumeView;
const before = view.last ? view.last.camera_version : -1;
const t0 = performance.now();
const onFrame = (e) => {
  if (e.detail.camera_version > before) {
    window.removeEventListener("raylume-frame", onFrame);
    done(performance.now() - t0);
  }
};
window.addEventListener("raylume-frame", onFrame);
view.send({type: "orbit", dx: arguments[0], dy: 0});
"""


CORNELL = str(Path(__file__).resolve().parents[1] / "examples" / "cornell.toml")


def start_server(width: int, height: int, spp: int, threads: int | None, scene: list[str] | None = None):
    """`raylume view` of the seed (trace mode, looking at LOOK_AT), or of `scene` (its arguments)."""
    scene = scene or ["seed", "--mode", "trace", "--set", f"camera.look_at={LOOK_AT}"]
    args = [sys.executable, "-m", "raylume.cli", "view", *scene, "--width", str(width)]
    args += ["--height", str(height), "--spp", str(spp), "--port", "0", "--no-browser"]
    if threads:
        args += ["--threads", str(threads)]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    ready, _, _ = select.select([proc.stdout], [], [], 120)
    if not ready:
        proc.kill()
        raise SystemExit("raylume view printed no URL")
    return proc, proc.stdout.readline().split(": ", 1)[1].strip()


def open_browser(width: int, height: int):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium")
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(arg)
    # room for the page at 1:1 (headless Chromium's viewport is ~140 px lower than its window)
    options.add_argument(f"--window-size={max(800, width + 100)},{max(600, height + 300)}")
    return webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)


def stats(url: str) -> dict:
    base, _, token = url.partition("/?token=")
    return json.loads(urllib.request.urlopen(f"{base}/stats?token={token}", timeout=30).read())


def wait_until(predicate, timeout: float = 120.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return
        time.sleep(0.02)
    raise SystemExit("timed out")


def drawn(driver) -> tuple[int, int, int]:
    """(frames drawn by the page, the last drawn frame's spp, pixels drawn in all)."""
    state = driver.execute_script("const v = window.raylumeView; return [v.drawn, v.last ? v.last.spp : 0, v.pixels];")
    return state[0], state[1], state[2]


def orbit_fps(driver, seconds: float) -> tuple[float, float]:
    """(frames drawn per second, their mean share of the view's pixels) during a drag of
    `seconds`: 4-pixel steps every STEP_MS, right then back left, so the pointer stays on the
    canvas."""
    from selenium.webdriver.common.action_chains import ActionChains

    canvas = driver.find_element("id", "view")
    steps = int(seconds * 1000 / STEP_MS)
    chain = ActionChains(driver, duration=STEP_MS)
    chain.move_to_element(canvas).click_and_hold()
    for k in range(steps):
        chain.move_by_offset(4 if (k // 20) % 2 == 0 else -4, 0)
    chain.release()
    n0, _, p0 = drawn(driver)
    t0 = time.perf_counter()
    chain.perform()
    elapsed = time.perf_counter() - t0
    n1, _, p1 = drawn(driver)
    pixels = driver.execute_script("const c = document.getElementById('view'); return c.width * c.height;")
    return (n1 - n0) / elapsed, (p1 - p0) / max(n1 - n0, 1) / pixels


def rest_fps(driver, url: str) -> tuple[float, float]:
    """(frames drawn per second while a 64-spp film refines at rest, seconds to converge)."""
    wait_until(lambda: stats(url)["converged"])  # the previous camera's film
    version = stats(url)["camera_version"]
    driver.execute_script("window.raylumeView.send({type: 'orbit', dx: 3, dy: 0});")
    t0 = time.perf_counter()

    def shown() -> dict:
        return driver.execute_script("return window.raylumeView.last;")

    wait_until(lambda: shown()["camera_version"] > version and shown()["format"] == "png")  # resting
    n0, t1 = drawn(driver)[0], time.perf_counter()
    wait_until(lambda: shown()["camera_version"] > version and shown()["converged"])
    n1, t2 = drawn(driver)[0], time.perf_counter()
    return (n1 - n0) / max(t2 - t1, 1e-9), t2 - t0


def latencies(driver, count: int = 15) -> list[float]:
    out = []
    for _ in range(count):
        out.append(driver.execute_async_script(GESTURE_LATENCY_JS, 5))
        time.sleep(0.25)  # let it rest, so each gesture starts from a still camera
    return out


def measure(width: int, height: int, seconds: float, threads: int | None, screenshot: str | None) -> list[str]:
    proc, url = start_server(width, height, 64, threads)
    driver = open_browser(width, height)
    try:
        driver.set_script_timeout(30)
        driver.get(url)
        wait_until(lambda: stats(url)["converged"] and drawn(driver)[0] > 0)
        orbit, share = zip(*[orbit_fps(driver, seconds) for _ in range(3)])
        mrays = stats(url)["mrays_per_second"]
        rest, converge = zip(*[rest_fps(driver, url) for _ in range(3)])
        lat = latencies(driver)
        if screenshot:
            driver.execute_script("window.raylumeView.send({type: 'reset'});")
            driver.execute_script("window.raylumeView.send({type: 'orbit', dx: -30, dy: 10});")
            time.sleep(0.5)
            wait_until(lambda: stats(url)["converged"])
            time.sleep(1.2)  # the fps shown by the page is polled once a second
            driver.find_element("tag name", "main").screenshot(screenshot)
    finally:
        driver.quit()
        proc.terminate()
        proc.wait(10)
    return [
        f"{width} x {height}",
        f"{statistics.median(orbit):.1f}",
        f"{math.sqrt(statistics.median(share)):.2f}",
        f"{statistics.median(rest):.1f}",
        f"{statistics.median(converge):.2f}",
        f"{statistics.median(lat):.0f} / {max(lat):.0f}",
        f"{mrays:.1f}",
    ]


def denoised_share(driver) -> tuple[int, int]:
    """(frames drawn, of them denoised) so far."""
    return tuple(driver.execute_script("const v = window.raylumeView; return [v.drawn, v.denoised];"))


def path_run(denoise: bool, seconds: float, threads: int | None) -> dict:
    """One server and browser: the Cornell box at 320 x 240 in path mode orbiting for `seconds`
    (three drags), with or without --denoise."""
    scene = [CORNELL, "--mode", "path", *(["--denoise"] if denoise else [])]
    proc, url = start_server(320, 240, 16, threads, scene)
    driver = open_browser(320, 240)
    try:
        driver.set_script_timeout(30)
        driver.get(url)
        wait_until(lambda: drawn(driver)[0] > 0, timeout=600)  # a first, cold compile takes long
        # warm: drag until a drag draws frames. The moving frames' kernels (and --denoise's filter)
        # load from the cache, or with an empty cache compile, on the first moving frame, and a
        # drag draws nothing until they have (a quick run measured 0 fps denoised after one drag)
        wait_until(lambda: orbit_fps(driver, 1.0)[0] > 0, timeout=600)
        n0, d0 = denoised_share(driver)
        fps, share = zip(*[orbit_fps(driver, seconds / 3) for _ in range(3)])
        n1, d1 = denoised_share(driver)
        s = stats(url)
        assert s["denoise"] is denoise and s["integrator"] == "path", s
        return {
            "fps": statistics.median(fps),
            "resolution": math.sqrt(statistics.median(share)),
            "denoised": (d1 - d0) / max(n1 - n0, 1),
            "mrays": s["mrays_per_second"],
        }
    finally:
        driver.quit()
        proc.terminate()
        proc.wait(10)


def path_table(runs: int, seconds: float, threads: int | None) -> list[list[str]]:
    results: dict[bool, list[dict]] = {False: [], True: []}
    for _ in range(runs):
        for denoise in (False, True):  # alternating: the machine's load drifts
            results[denoise].append(path_run(denoise, seconds, threads))
    rows = []
    for denoise, rs in results.items():
        rows.append(
            [
                "on" if denoise else "off",
                f"{statistics.median(r['fps'] for r in rs):.1f}",
                ", ".join(f"{r['fps']:.1f}" for r in rs),
                f"{statistics.median(r['resolution'] for r in rs):.2f}",
                f"{statistics.median(r['denoised'] for r in rs):.2f}",
                f"{statistics.median(r['mrays'] for r in rs):.1f}",
            ]
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="320x240,640x480")
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--screenshot", default=None, help="save the page at the last size as this PNG")
    parser.add_argument("--only", choices=("trace", "path"), default=None, help="one of the two tables")
    parser.add_argument("--runs", type=int, default=3, help="path mode: runs with and without --denoise each")
    args = parser.parse_args()
    missing = [name for name in ("chromium", "chromedriver") if shutil.which(name) is None]
    try:
        import selenium  # noqa: F401
    except ImportError:
        missing.append("selenium")
    if missing:
        print(f"bench_view skipped: no {', '.join(missing)} (Debian's chromium and chromium-driver; the dev extra)")
        return
    threads = f"{args.threads or os.cpu_count()} render threads"
    if args.only != "path":
        sizes = [tuple(int(v) for v in size.split("x")) for size in args.sizes.split(",")]
        load = os.getloadavg()
        rows = [
            measure(w, h, args.seconds, args.threads, args.screenshot if k == len(sizes) - 1 else None)
            for k, (w, h) in enumerate(sizes)
        ]
        print(f"raylume view, seed scene, trace mode; {machine()}; {threads}\n")
        headers = ["size", "fps orbiting", "resolution orbiting", "fps at rest (64 spp)", "s to 64 spp"]
        print(table([*headers, "gesture -> frame ms (median / max)", "Mrays/s orbiting"], rows))
        print(f"\nload average before / after: {load[0]:.1f} / {os.getloadavg()[0]:.1f}")
        print(f"\n(medians of 3 runs of {args.seconds:.0f} s each; latency over 15 gestures)\n")
    if args.only != "trace":
        load = os.getloadavg()
        rows = path_table(args.runs, args.seconds, args.threads)
        print(f"raylume view, Cornell box, path mode, 320 x 240, orbiting; {machine()}; {threads}\n")
        headers = ["--denoise", "fps orbiting (median)", "each run", "resolution orbiting", "frames denoised"]
        print(table([*headers, "Mrays/s orbiting"], rows))
        print(f"\nload average before / after: {load[0]:.1f} / {os.getloadavg()[0]:.1f}")
        print(
            f"\n({args.runs} runs each, alternating; each run's fps the median of 3 drags of {args.seconds / 3:.0f} s)"
        )


if __name__ == "__main__":
    run_main(main)
