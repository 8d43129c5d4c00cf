"""Reading a scene file's text, with the one-line errors that name the file (a missing file, a
folder, an unreadable or undecodable one) that every scene reader gives."""

from __future__ import annotations

from pathlib import Path

from ..errors import SceneError


def read_scene_text(path: Path, what: str = "scene file", error: type[SceneError] = SceneError) -> str:
    """The UTF-8 text of `path`, a `what` (a byte-order mark, as Windows' Notepad writes, left
    out); else `error` with one line naming it."""
    if path.is_dir():
        raise error(f"{path}: is a folder, not a {what}")
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{path}: cannot read the {what} ({exc})") from None
