"""Pages generated at `mkdocs build` time (mkdocs-gen-files): the scene file and command-line references
from the code, and the gallery from tools/gallery.py's table. The performance page is not generated: it is
docs/performance.md, every benchmark's tables and their history (the README shows the latest of each)."""

from __future__ import annotations

import sys
from pathlib import Path

import mkdocs_gen_files

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))

import docs_reference  # noqa: E402
import gallery  # noqa: E402


def gallery_page() -> str:
    lines = [
        "# Gallery",
        "",
        "Every picture the documentation shows, with the exact command that made it, run from the repository's "
        "root (`make gallery`, i.e. `python tools/gallery.py`, runs them all). The test suite renders each again "
        "from its command at a small size and compares it with the committed picture's downscale, and renders a "
        "window of it at full size with `--crop` and compares that pixel by pixel (a denoised picture's window "
        "within a margin, as the denoiser sees only the window; not for "
        + ", ".join(p.name for p in gallery.PICTURES if p.crop_part is None)
        + ", whose tools/gallery.py entries say why), so a picture that no longer matches what its "
        "command renders fails the suite (`tests/test_gallery.py`; the tolerances, and the differences they were "
        "measured against, are in `tools/gallery.py`).",
        "",
    ]
    for picture in gallery.PICTURES:
        lines += [f"## {picture.title}", "", f"![{picture.name}](images/{picture.path.name})", ""]
        if picture.setup:
            lines += ["```sh", " ".join(picture.setup), picture.command, "```", ""]
        else:
            lines += ["```sh", picture.command, "```", ""]
        if picture.note:
            lines += [picture.note, ""]
    lines += [
        "The plots on the performance page are drawn by the benchmarks named beside them, and the live view's "
        "screenshot by `python benchmarks/bench_view.py --screenshot docs/images/view.png`.",
        "",
    ]
    return "\n".join(lines)


PAGES = {
    "reference/scene.md": docs_reference.scene_reference_markdown,
    "reference/cli.md": docs_reference.cli_reference_markdown,
    "gallery.md": gallery_page,
}

for name, make in PAGES.items():
    with mkdocs_gen_files.open(name, "w") as page:
        page.write(make())
