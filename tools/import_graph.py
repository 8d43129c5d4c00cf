"""raylume's import graph, read from the sources (ast): its circles and the imports that run against
the layers (docs/architecture.md, "Rooms and layers"). tests/test_architecture.py asserts both are
empty; run this to see them:

    python tools/import_graph.py [SRC_DIR]

Every import counts, at the top of a module or inside a function (a function's import is still a
dependency), except those under `if TYPE_CHECKING:`, which never run."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"

# What each layer may import of raylume, by module-name prefix (the first matching rule wins).
LAYERS = (
    ("raylume.kernels", ("raylume.kernels",)),
    ("raylume.accel", ("raylume.accel", "raylume.kernels")),
    ("raylume.scene", ("raylume.scene", "raylume.errors")),
)


def modules(src: Path = SRC) -> dict[str, Path]:
    """Module name -> file of every module of the raylume package."""
    found = {}
    for path in sorted((src / "raylume").rglob("*.py")):
        parts = list(path.relative_to(src).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def _runtime_nodes(tree: ast.AST):
    """The tree's nodes, less the bodies of `if TYPE_CHECKING:` blocks."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                stack.extend(child.orelse)
                continue
            stack.append(child)


def imports(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The raylume modules that module `name` imports."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in _runtime_nodes(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.add(sub if sub in known else target)
    return {m for m in found if m in known and m != name}


def graph(src: Path = SRC) -> dict[str, set[str]]:
    known = modules(src)
    return {name: imports(name, path, known) for name, path in known.items()}


def circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    sys.setrecursionlimit(10000)
    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def against_layers(edges: dict[str, set[str]]) -> list[tuple[str, str]]:
    """(importer, imported) pairs that a layer rule forbids."""
    bad = []
    for name, targets in sorted(edges.items()):
        for prefix, allowed in LAYERS:
            if name == prefix or name.startswith(prefix + "."):
                bad += [(name, t) for t in sorted(targets) if not any(t == a or t.startswith(a + ".") for a in allowed)]
                break
    return bad


def main() -> int:
    src = Path(sys.argv[1]) if len(sys.argv) > 1 else SRC
    edges = graph(src)
    found = circles(edges)
    bad = against_layers(edges)
    for component in found:
        print(f"circle ({len(component)} modules): {', '.join(component)}")
    for name, target in bad:
        print(f"against the layers: {name} imports {target}")
    counts = f"{len(edges)} modules, {sum(map(len, edges.values()))} imports"
    print(f"{counts}, {len(found)} circles, {len(bad)} against the layers")
    return 1 if found or bad else 0


if __name__ == "__main__":
    sys.exit(main())
