"""The documentation cannot rot: every Python block of README.md and docs/ runs as written, each by
itself in a fresh interpreter in an empty folder (as a person copies it into a file in a clone:
`examples/` is there, nothing else); every `raylume ...` line in their fenced blocks parses against
the command itself, its --set keys included; every TOML block validates as a scene; the generated
references cover the whole scene model and every flag. A block that is deliberately not runnable
starts with the visible line `# (not run by the test suite: WHY)`."""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
NOT_RUN = "# (not run by the test suite:"
DOCUMENTS = [REPO / "README.md", *sorted((REPO / "docs").glob("**/*.md"))]


def _load_tool(name: str):
    spec = importlib.util.spec_from_file_location(name, REPO / "tools" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


docs_reference = _load_tool("docs_reference")


@dataclass(frozen=True)
class Block:
    path: Path
    line: int  # of the opening fence, from 1
    language: str
    text: str

    @property
    def label(self) -> str:
        return f"{self.path.relative_to(REPO)}:{self.line}"


def fenced_blocks(path: Path) -> list[Block]:
    blocks, lines = [], path.read_text().split("\n")
    k = 0
    while k < len(lines):
        match = re.match(r"^(\s*)```(\w*)", lines[k])
        if match:
            indent, language, start = match.group(1), match.group(2), k
            k += 1
            body = []
            while k < len(lines) and not lines[k].strip().startswith("```"):
                body.append(lines[k][len(indent) :])
                k += 1
            blocks.append(Block(path, start + 1, language, "\n".join(body) + "\n"))
        k += 1
    return blocks


ALL_BLOCKS = [block for path in DOCUMENTS for block in fenced_blocks(path)]
PYTHON_BLOCKS = [b for b in ALL_BLOCKS if b.language == "python"]


def test_documents_have_python_blocks_and_few_are_not_run():
    assert len(PYTHON_BLOCKS) >= 8 and len([b for b in ALL_BLOCKS if b.language == "toml"]) >= 5
    not_run = [b.label for b in PYTHON_BLOCKS if b.text.startswith(NOT_RUN)]
    assert len(not_run) <= 2, f"keep blocks that are not run rare: {not_run}"


def _block_param(block: Block):
    marks = []
    if "LocalCluster" in block.text or 'cluster="local' in block.text:
        marks.append(pytest.mark.xdist_group("cluster"))  # one local cluster at a time, as tests/test_cluster.py
    if block.text.startswith(NOT_RUN):
        marks.append(pytest.mark.skip(reason=block.text.splitlines()[0].removeprefix("# (").removesuffix(")")))
    return pytest.param(block, id=block.label, marks=marks)


@pytest.mark.parametrize("block", [_block_param(b) for b in PYTHON_BLOCKS])
def test_python_block_runs_as_written(block: Block, tmp_path):
    (tmp_path / "examples").symlink_to(REPO / "examples")
    script = tmp_path / "example.py"
    script.write_text(block.text)
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    result = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, f"{block.label} failed:\n{result.stderr[-3000:]}"
    assert "Traceback" not in result.stderr, f"{block.label} printed a traceback:\n{result.stderr[-3000:]}"


# Command lines: `raylume ...` in shell blocks (a line may start it after `$ `, `.venv/bin/`, `ssh ... host`).
SYNOPSIS_LANGUAGES = {"text"}  # the synopsis: placeholders in brackets, checked flag by flag below


def raylume_command_lines() -> list[tuple[str, list[str]]]:
    found = []
    for block in ALL_BLOCKS:
        if block.language not in ("sh", "bash", "console", "shell", ""):
            continue
        for offset, line in enumerate(block.text.splitlines(), start=1):
            try:
                tokens = shlex.split(line, comments=True)
            except ValueError:
                continue
            for start, token in enumerate(tokens):
                if token.endswith("raylume") and (start == 0 or tokens[start - 1] not in ("-m",)):
                    args = []
                    for arg in tokens[start + 1 :]:
                        if arg in ("&", "&&", "|", ";", "||"):
                            break
                        args.append(arg)
                    found.append((f"{block.label}+{offset}", args))
                    break
    return found


COMMAND_LINES = raylume_command_lines()


def test_documents_show_command_lines():
    assert len(COMMAND_LINES) >= 20, COMMAND_LINES


@pytest.mark.parametrize("args", [pytest.param(args, id=label) for label, args in COMMAND_LINES])
def test_command_line_parses(args):
    docs_reference.parse_command_line(args)  # an unknown flag or command: CommandLineError
    for k, arg in enumerate(args):
        if arg == "--set":
            key = args[k + 1].split("=", 1)[0]
            assert docs_reference.scene_key_exists(key), f"--set {key}: no such scene key"


def test_the_checks_refuse_what_the_command_refuses():
    with pytest.raises(docs_reference.CommandLineError):
        docs_reference.parse_command_line(["render", "--no-such-flag"])
    with pytest.raises(docs_reference.CommandLineError):
        docs_reference.parse_command_line(["rendr", "scene.toml"])
    with pytest.raises(docs_reference.CommandLineError):
        docs_reference.parse_command_line(["render", "--spp", "many"])
    assert docs_reference.scene_key_exists("objects.2.radius")
    assert docs_reference.scene_key_exists("materials.glass.ior")
    assert docs_reference.scene_key_exists("camera.position")
    assert not docs_reference.scene_key_exists("camera.fob")
    assert not docs_reference.scene_key_exists("objects.radius")


def test_gallery_commands_parse():
    gallery = _load_tool("gallery")
    for picture in gallery.PICTURES:
        docs_reference.parse_command_line(["render", *picture.args, *picture.check_args])


def test_gallery_list_gives_each_setup_and_aligns_the_commands(capsys):
    gallery = _load_tool("gallery")
    gallery.main(["--list"])
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(gallery.PICTURES)
    assert len({len(line) - len(line.split(maxsplit=1)[1]) for line in lines}) == 1, "commands start in one column"
    for picture in gallery.PICTURES:
        line = next(line for line in lines if line.split()[0] == picture.name)
        assert line.endswith(picture.command)
        assert not picture.setup or f"{' '.join(picture.setup)} && raylume render" in line, line


def _synopsis_flags(command: str) -> set[str]:
    text = "".join(b.text for b in ALL_BLOCKS if b.path.name == "README.md" and b.language in SYNOPSIS_LANGUAGES)
    lines = re.findall(rf"^raylume {command} .*(?:\n {{10,}}.*)*", text, flags=re.M)
    assert lines, f"README's synopsis has no `raylume {command}` line"
    return set(re.findall(r"(?<![\w-])(-{1,2}[a-z][\w-]*)", "\n".join(lines)))


@pytest.mark.parametrize("command", ["render", "view"])
def test_readme_synopsis_lists_every_flag(command):
    cmd = docs_reference.cli_group().commands[command]
    options = [p.opts for p in cmd.params if p.param_type_name == "option" and "--help" not in p.opts]
    shown = _synopsis_flags(command)
    missing = [opts[0] for opts in options if not shown & set(opts)]
    assert not missing, f"README's `raylume {command}` synopsis lacks {missing}"
    unknown = shown - {opt for opts in options for opt in opts}
    assert not unknown, f"README's `raylume {command}` synopsis shows flags the command lacks: {sorted(unknown)}"


TOML_BLOCKS = [b for b in ALL_BLOCKS if b.language == "toml"]


@pytest.mark.parametrize("block", [pytest.param(b, id=b.label) for b in TOML_BLOCKS])
def test_toml_block_is_a_valid_scene(block: Block):
    """Every scene file shown validates (its keys and values; a fragment's material and medium names stand for
    tables it leaves out; files it names are not read)."""
    from raylume.scene.model import Scene

    document = tomllib.loads(block.text)
    materials = document.setdefault("materials", {})
    media = document.setdefault("media", {})
    for obj in document.get("objects", []):
        if isinstance(obj.get("material"), str):
            materials.setdefault(obj["material"], {})
        if isinstance(obj.get("interior"), str):
            media.setdefault(obj["interior"], {"type": "homogeneous"})
    Scene.model_validate(document)


def test_scene_reference_covers_every_model_field():
    assert docs_reference.model_fields_reachable() <= docs_reference.covered_fields()
    page = docs_reference.scene_reference_markdown()
    for table in docs_reference.scene_tables():
        section = page.split(f"{{#{table.anchor}}}", 1)[1].split("\n## ", 1)[0]
        for name in table.model.model_fields:
            assert f"| `{name}` |" in section, f"{table.heading}: key {name} missing"
    assert '`"path"`' in page and '`"gltf"`' in page


def test_scene_reference_refuses_an_undocumented_field(monkeypatch):
    docs = docs_reference._attribute_docstrings()
    del docs[("RenderSettings", "spp")]
    monkeypatch.setattr(docs_reference, "_attribute_docstrings", lambda: docs)
    with pytest.raises(ValueError, match="RenderSettings.spp"):
        docs_reference.scene_reference_markdown()


def test_cli_reference_lists_every_option():
    page = docs_reference.cli_reference_markdown()
    group = docs_reference.cli_group()
    for name, command in group.commands.items():
        assert f"## raylume {name}" in page
        for param in command.params:
            if param.param_type_name == "option":
                assert f"`{param.opts[0]}`" in page, f"raylume {name} {param.opts[0]}"


def test_docs_name_no_other_machine():
    """Examples never name another machine's address: a cluster is local, local:N or a loopback address."""
    private = re.compile(r"\b(?:10|192\.168|172\.(?:1[6-9]|2\d|3[01]))\.\d{1,3}\.\d{1,3}(?:\.\d{1,3})?\b")
    for block in ALL_BLOCKS:
        assert not private.search(block.text), f"{block.label} names a private-network address"
        for address in re.findall(r"tcp://([\w.\-]+)", block.text):
            assert address in ("127.0.0.1", "localhost", "HOST", "SCHEDULER"), f"{block.label}: tcp://{address}"
