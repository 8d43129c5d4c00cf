"""Documents nested too deeply to read: where Python's recursion gives out (in the parser, the
copies for --set, the validation), the error names the file and the key path where they do."""

from __future__ import annotations

from ..errors import SceneError

# How deep tables and lists may nest before too_deep names the place: a scene needs fewer than
# ten levels, and Python's recursion gives out at a few hundred.
MAX_NESTING = 64


def too_deep(document, where: str) -> SceneError:
    """The error for a document that exhausted Python's recursion: the key path where its
    tables and lists nest more than MAX_NESTING deep (walked without recursion; only then, as
    inline meshes hold hundreds of thousands of short lists)."""
    stack = [(document, 0, None, "")]  # (container, depth, parent entry, key in the parent)
    while stack:
        entry = stack.pop()
        node, depth = entry[0], entry[1]
        if depth >= MAX_NESTING:
            return SceneError(
                f"{where}: {_key_path(entry)}: tables or lists nested more than {MAX_NESTING} levels deep"
            )
        children = node.items() if isinstance(node, dict) else enumerate(node)
        stack.extend((v, depth + 1, entry, k) for k, v in children if isinstance(v, (dict, list, tuple)))
    return SceneError(f"{where}: tables or lists nested too deeply")


def _key_path(entry, shown: int = 4) -> str:
    """The key path to a stack entry of too_deep, its first `shown` steps and then '...'."""
    keys = []
    while entry[2] is not None:
        keys.append(f"[{entry[3]}]" if isinstance(entry[3], int) else f".{entry[3]}")
        entry = entry[2]
    keys.reverse()
    return "".join(keys[:shown]).lstrip(".") + ("..." if len(keys) > shown else "")
