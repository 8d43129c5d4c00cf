"""Files a scene refers to that a script makes (examples/forest/make_forest.py writes the
forest's meshes and placements): when one is missing, the error names the script to run."""

from __future__ import annotations

import os
from pathlib import Path


def generator_hint(path: Path) -> str:
    """'; made by SCRIPT: run `python SCRIPT`' when a `make_*.py` beside the missing file
    `path` names it (its file name appears in the script's text), else ''. SCRIPT is given
    relative to the working folder where it lies below it."""
    folder = Path(path).parent
    try:
        scripts = sorted(folder.glob("make_*.py"))
    except OSError:
        return ""
    for script in scripts:
        try:
            text = script.read_text(encoding="utf-8", errors="replace")
        except OSError:
            continue
        if Path(path).name in text:
            shown = _relative(script)
            return f"; it is generated: run `python {shown}` first"
    return ""


def _relative(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(Path(os.getcwd()).resolve()))
    except ValueError:
        return str(path)
