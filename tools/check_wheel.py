"""Check raylume's wheel as a new user meets it: installed alone (with the denoise extra) into a
new virtual environment, run from an empty folder with an empty Numba cache, nothing of this
checkout on sys.path. `make wheel` and .ci/run run it:

    python tools/check_wheel.py [WHEEL]     # default: build one (python -m build) into a temp folder

It checks that the wheel holds the package data (built-in scenes, the view's page), then in
that folder: `raylume render` (the built-in scene), `raylume render cornell.toml --mode path
--denoise` (an example copied there with the meshes it names), and `raylume view` for a few
seconds (its /stats and a frame over 127.0.0.1, then Ctrl-C: exit 130). Dependencies come
from the package registry through pip's own cache, so a second run downloads nothing.
Prints what it did and exits non-zero on the first failure."""

from __future__ import annotations

import argparse
import io
import json
import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# files the package reads at run time (importlib.resources), and the PEP 561 marker that lets type
# checkers read its annotations: they must be in the wheel
PACKAGE_DATA = (
    "raylume/py.typed",
    "raylume/scenes/seed.toml",
    "raylume/viewer/static/index.html",
    "raylume/viewer/static/view.js",
)


def step(message: str) -> None:
    print(f"check_wheel: {message}", flush=True)


def run(args: list, **kwargs) -> subprocess.CompletedProcess:
    result = subprocess.run([str(a) for a in args], capture_output=True, text=True, **kwargs)
    if result.returncode != 0:
        command = " ".join(map(str, args))
        sys.exit(f"check_wheel: {command} failed ({result.returncode}):\n{result.stdout}{result.stderr}")
    return result


def build_wheel(out: Path) -> Path:
    step("python -m build (sdist, and the wheel from it)")
    run([sys.executable, "-m", "build", "--outdir", out, REPO])
    return next(out.glob("raylume-*.whl"))


def check_contents(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = [name for name in PACKAGE_DATA if name not in names]
    if missing:
        sys.exit(f"check_wheel: {wheel.name} lacks {', '.join(missing)}")
    stray = sorted(n for n in names if n.split("/")[0] in ("tests", "benchmarks", "tools", "examples"))
    if stray:
        sys.exit(f"check_wheel: {wheel.name} holds files outside the package: {stray[:5]}")
    step(f"{wheel.name}: {len(names)} files, the package data included")


def install(wheel: Path, venv: Path) -> Path:
    step(f"a new environment in {venv}: pip install {wheel.name}[denoise]")
    run([sys.executable, "-m", "venv", venv])
    python = venv / "bin" / "python"
    run([python, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", f"{wheel}[denoise]"])
    return venv / "bin" / "raylume"


def isolated_env(cache: Path) -> dict:
    """The environment of a new user: no PYTHONPATH (nothing of this checkout importable), an
    empty Numba cache of its own."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["NUMBA_CACHE_DIR"] = str(cache)
    return env


def check_not_from_checkout(raylume: Path, folder: Path, env: dict) -> None:
    python = raylume.parent / "python"
    where = run([python, "-c", "import raylume; print(raylume.__file__)"], cwd=folder, env=env).stdout.strip()
    if str(REPO) in where or "site-packages" not in where:
        sys.exit(f"check_wheel: raylume imported from {where}, not from the installed wheel")


def render(raylume: Path, folder: Path, env: dict, *args: str) -> None:
    started = time.perf_counter()
    result = run([raylume, "render", *args], cwd=folder, env=env)
    summary = result.stderr.strip().splitlines()[-1] if result.stderr.strip() else ""
    step(f"raylume render {' '.join(args)}: {time.perf_counter() - started:.1f} s; {summary}")


def check_png(path: Path, size: tuple[int, int]) -> None:
    from PIL import Image

    with Image.open(path) as image:
        if image.size != size:
            sys.exit(f"check_wheel: {path.name} is {image.size}, expected {size}")
        if max(high for _, high in image.convert("RGB").getextrema()) == 0:
            sys.exit(f"check_wheel: {path.name} is black")


def view(raylume: Path, folder: Path, env: dict) -> None:
    """`raylume view` on a free port: its URL first on stdout, /stats and a frame, Ctrl-C -> 130."""
    from PIL import Image

    args = ["view", "seed", "--mode", "path", "--width", "32", "--height", "24", "--port", "0", "--no-browser"]
    proc = subprocess.Popen([str(raylume), *args], cwd=folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)  # fmt: skip
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 120)
        line = proc.stdout.readline().strip() if ready else ""
        if not line.startswith("raylume view: http://127.0.0.1:"):
            sys.exit(f"check_wheel: raylume view printed {line!r} first")
        url = line.split(": ", 1)[1]
        base, _, token = url.partition("/?token=")
        with urllib.request.urlopen(f"{base}/stats?token={token}", timeout=30) as response:
            stats = json.loads(response.read())
        if (stats["width"], stats["height"], stats["mode"]) != (32, 24, "path"):
            sys.exit(f"check_wheel: /stats says {stats}")
        with urllib.request.urlopen(f"{base}/frame.png?token={token}", timeout=300) as response:
            frame = Image.open(io.BytesIO(response.read()))
            if frame.size != (32, 24):
                sys.exit(f"check_wheel: /frame.png is {frame.size}")
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=30)
        if code != 130:
            sys.exit(f"check_wheel: raylume view exited {code} on Ctrl-C, not 130:\n{proc.stderr.read()}")
        step(f"raylume view: /stats {stats['frames']} frames, /frame.png {frame.size}, Ctrl-C: exit 130")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("wheel", nargs="?", type=Path, help="a built wheel (default: build one now)")
    parser.add_argument("--keep", action="store_true", help="keep the temporary folder (its path is printed)")
    args = parser.parse_args()
    top = Path(tempfile.mkdtemp(prefix="raylume-wheel-"))
    try:
        wheel = args.wheel.resolve() if args.wheel else build_wheel(top / "dist")
        check_contents(wheel)
        raylume = install(wheel, top / "venv")
        folder = top / "empty"  # the user's folder: nothing in it but what the steps copy
        folder.mkdir()
        env = isolated_env(top / "numba-cache")
        check_not_from_checkout(raylume, folder, env)
        render(raylume, folder, env, "--width", "64", "--height", "64")  # the built-in scene
        check_png(folder / "render.png", (64, 64))
        shutil.copy(REPO / "examples" / "cornell.toml", folder)
        shutil.copytree(REPO / "examples" / "cornell", folder / "cornell")
        render(raylume, folder, env, "cornell.toml", "-o", "cornell.png", "--mode", "path", "--width", "48",
               "--height", "48", "--spp", "4", "--denoise")  # fmt: skip
        check_png(folder / "cornell.png", (48, 48))
        view(raylume, folder, env)
        step("the wheel renders, views and denoises from an empty folder")
    finally:
        if args.keep:
            step(f"kept {top}")
        else:
            shutil.rmtree(top, ignore_errors=True)


if __name__ == "__main__":
    main()
