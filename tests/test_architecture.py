"""The package's shape (docs/architecture.md, "Rooms and layers"): no import circles, imports that
run one way between the layers, and a kernel cache whose key covers everything compiled into a
kernel. The import graph is read from the sources by tools/import_graph.py."""

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import raylume

SRC = Path(raylume.__file__).resolve().parents[1]
ROOT = SRC.parent


def _import_graph():
    spec = importlib.util.spec_from_file_location("import_graph", ROOT / "tools" / "import_graph.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_import_graph_has_no_circles():
    graph = _import_graph()
    assert graph.circles(graph.graph(SRC)) == []


def test_imports_run_one_way_between_the_layers():
    """Kernels import only kernels; accel only accel and kernels; the scene model nothing of
    compiling or rendering."""
    graph = _import_graph()
    assert graph.against_layers(graph.graph(SRC)) == []


def test_the_graph_reader_sees_circles_and_back_imports(tmp_path):
    """The reader itself, on a made-up package: a circle through a function-level import, and a
    kernel importing the compiler."""
    package = tmp_path / "raylume"
    (package / "kernels").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "kernels" / "__init__.py").write_text("")
    (package / "kernels" / "a.py").write_text("from . import b\n")
    (package / "kernels" / "b.py").write_text("def f():\n    from .a import g\n    from ..compile import h\n")
    (package / "compile.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import kernels\n"
    )
    graph = _import_graph()
    edges = graph.graph(tmp_path)
    assert graph.circles(edges) == [["raylume.kernels.a", "raylume.kernels.b"]]
    assert graph.against_layers(edges) == [("raylume.kernels.b", "raylume.compile")]
    assert edges["raylume.compile"] == set()  # imports under TYPE_CHECKING never run


def _cache_dir(src: Path, tmp_path: Path) -> str:
    """numba.config.CACHE_DIR as a fresh process that imports raylume.kernels from `src` sets it."""
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    code = "import numba, raylume.kernels; print(numba.config.CACHE_DIR)"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return out.stdout.strip()


def test_a_changed_node_layout_constant_moves_the_kernel_cache(tmp_path):
    """The node layout (kernels/geometry/layout.py) is compiled into every traversal kernel: a
    change to it must give the kernels a new cache folder (a recompile), never stale machine
    code. Numba itself checks only the entry point's file."""
    copy = tmp_path / "src"
    shutil.copytree(SRC / "raylume", copy / "raylume", ignore=shutil.ignore_patterns("__pycache__"))
    before = _cache_dir(copy, tmp_path)
    layout = copy / "raylume" / "kernels" / "geometry" / "layout.py"
    text = layout.read_text()
    assert "SPHERE_BLOCK = 8" in text
    layout.write_text(text.replace("SPHERE_BLOCK = 8", "SPHERE_BLOCK = 16"))
    after = _cache_dir(copy, tmp_path)
    assert before != after
    assert Path(before).parent == Path(after).parent == tmp_path / "cache"
    # ... and the same sources give the same folder (the cache is kept between processes)
    layout.write_text(text)
    assert _cache_dir(copy, tmp_path) == before
