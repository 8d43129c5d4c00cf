"""The Makefile installs what each target needs: rendering alone, tests (dev), benchmarks (dev, bench)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")


def dry_run(target: str, venv: Path) -> list[str]:
    """The pip install lines `make -n TARGET` would run for a venv at `venv`."""
    result = subprocess.run(
        ["make", "-n", "-C", str(REPO), target, f"VENV={venv}"], capture_output=True, text=True, check=False
    )
    assert result.returncode == 0, result.stderr
    return [line for line in result.stdout.splitlines() if "pip install" in line and "--upgrade pip" not in line]


def test_render_installs_no_extras(tmp_path):
    installs = dry_run("render", tmp_path / "venv")
    assert len(installs) == 1 and installs[0].rstrip().endswith("-e ."), installs


def test_test_and_bench_install_their_extras(tmp_path):
    assert any("'.[dev]'" in line for line in dry_run("test", tmp_path / "venv"))
    assert any("'.[dev,bench]'" in line for line in dry_run("bench", tmp_path / "venv"))


def test_bench_installs_the_debian_packages_it_uses(tmp_path):
    """make bench asks tools/apt_install.sh for Mitsuba's libLLVM and the browser before the benchmarks run."""
    result = subprocess.run(
        ["make", "-n", "-C", str(REPO), "bench", f"VENV={tmp_path / 'venv'}"], capture_output=True, text=True
    )
    lines = result.stdout.splitlines()
    apt = [i for i, line in enumerate(lines) if "tools/apt_install.sh" in line]
    runs = [i for i, line in enumerate(lines) if "benchmarks/run_all.py" in line]
    assert apt and runs and apt[0] < runs[0], result.stdout
    assert {"libllvm19", "chromium", "chromium-driver"} <= set(lines[apt[0]].split())


@pytest.mark.skipif(shutil.which("dpkg-query") is None, reason="not a Debian system (no dpkg-query)")
def test_apt_install_leaves_installed_packages_alone():
    """Packages already installed (dpkg's own here) need no apt-get: nothing printed, status 0."""
    result = subprocess.run(
        ["bash", str(REPO / "tools" / "apt_install.sh"), "dpkg"], capture_output=True, text=True, timeout=60
    )
    assert (result.returncode, result.stdout, result.stderr) == (0, "", "")


def test_render_then_test_still_installs_dev(tmp_path):
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").touch()
    # what `make render` leaves behind: the venv and the render stamp only
    for stamp in dry_run_stamps("render", venv):
        Path(stamp).touch()
    assert any("'.[dev]'" in line for line in dry_run("test", venv))


def dry_run_stamps(target: str, venv: Path) -> list[str]:
    result = subprocess.run(
        ["make", "-n", "-C", str(REPO), target, f"VENV={venv}"], capture_output=True, text=True, check=False
    )
    return [word for line in result.stdout.splitlines() if line.startswith("touch ") for word in line.split()[1:]]


def test_docs_installs_the_docs_extra_and_builds_strictly(tmp_path):
    installs = dry_run("docs", tmp_path / "venv")
    assert len(installs) == 1 and installs[0].rstrip().endswith("-e '.[docs]'"), installs
    build = subprocess.run(
        ["make", "-n", "-C", str(REPO), "docs", f"VENV={tmp_path / 'venv'}"], capture_output=True, text=True, check=True
    ).stdout
    assert "mkdocs build --strict" in build
    assert "make docs" in (REPO / ".ci" / "run").read_text()


def test_wheel_builds_and_checks_with_the_dev_extras(tmp_path):
    result = subprocess.run(
        ["make", "-n", "-C", str(REPO), "wheel", f"VENV={tmp_path / 'venv'}"], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert any("'.[dev]'" in line for line in lines)  # `build` is a dev extra
    assert any("-m build" in line for line in lines) and any("tools/check_wheel.py" in line for line in lines)


def test_every_data_file_of_the_package_goes_into_the_wheel():
    """Files of src/raylume other than Python that the package reads at run time are package
    data in pyproject.toml, and tools/check_wheel.py looks for each in the wheel."""
    import fnmatch
    import sys
    import tomllib

    sys.path.insert(0, str(REPO / "tools"))
    try:
        from check_wheel import PACKAGE_DATA
    finally:
        sys.path.pop(0)
    package = REPO / "src" / "raylume"
    data = sorted(
        p.relative_to(package).as_posix()
        for p in package.rglob("*")
        if p.is_file() and p.suffix not in (".py", ".pyc") and "__pycache__" not in p.parts
    )
    globs = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["raylume"]
    assert data and all(any(fnmatch.fnmatch(name, g) for g in globs) for name in data), (data, globs)
    assert sorted(name.removeprefix("raylume/") for name in PACKAGE_DATA) == data


def test_installs_compile_the_bytecode(tmp_path):
    """After an editable install each target compiles raylume's bytecode (as pip does a wheel's),
    so that the first render does not."""
    result = subprocess.run(
        ["make", "-n", "-C", str(REPO), "render", f"VENV={tmp_path / 'venv'}"], capture_output=True, text=True
    )
    lines = result.stdout.splitlines()
    install = next(k for k, line in enumerate(lines) if "pip install" in line and "-e ." in line)
    assert any("compileall" in line and "src" in line for line in lines[install + 1 :]), lines
