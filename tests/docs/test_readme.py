"""The README's shell commands parse as written, and every relative link of the README and the
docs pages points at a file that exists."""

from __future__ import annotations

import functools
import importlib.util
import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

from assocbench.cli.main import build_parser

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)


def shell_commands(text: str) -> list[str]:
    """The commands of the ``bash`` blocks: continuation lines joined, comments dropped, split at
    ``&&``, ``;`` and ``|``."""
    out = []
    for lang, body in FENCE.findall(text):
        if lang not in ("bash", "sh"):
            continue
        for line in body.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            command: list[str] = []
            for word in [*words, "&&"]:
                if word in ("&&", ";", "|", "&"):
                    if command:
                        out.append(command)
                    command = []
                else:
                    command.append(word)
    return out


def assocbench_args(command: list[str]) -> list[str] | None:
    """The arguments of an ``assocbench`` command (after any ``VAR=value``), else None."""
    words = [w for w in command if not re.match(r"^[A-Z_]+=", w)] if command else []
    return words[1:] if words and Path(words[0]).name == "assocbench" else None


README_COMMANDS = [args for c in shell_commands((ROOT / "README.md").read_text()) if (args := assocbench_args(c)) is not None]


def test_readme_has_the_commands_it_promises():
    assert ["run", "--method", "jcbb", "--scene", "park"] in README_COMMANDS
    assert ["run", "--method", "projective", "--scene", "crates", "--frames", "20"] in README_COMMANDS
    assert len(README_COMMANDS) >= 10
    assert len((ROOT / "README.md").read_text().splitlines()) <= 200


@pytest.mark.parametrize("args", README_COMMANDS, ids=[" ".join(a) for a in README_COMMANDS])
def test_readme_assocbench_command_parses(args):
    parser = build_parser()
    parsed, extra = parser.parse_known_args(args)   # argparse exits (SystemExit) on a bad command
    assert extra == [] and parsed.command == args[0]


def test_docs_assocbench_commands_parse():
    bad = []
    for page in PAGES[1:]:
        for command in shell_commands(page.read_text()):
            args = assocbench_args(command)
            if args is None:
                continue
            try:
                _, extra = build_parser().parse_known_args(args)
            except SystemExit:
                extra = ["(refused)"]
            if extra:
                bad.append(f"{page.relative_to(ROOT)}: assocbench {' '.join(args)} -> {extra}")
    assert bad == []


def relative_links(text: str) -> list[str]:
    """Link and image targets outside code blocks and code spans, without web addresses or
    anchors of the same page."""
    text = re.sub(r"`[^`\n]*`", "", FENCE.sub("", text))
    targets = re.findall(r"!?\[[^\]]*\]\(([^)\s]+)\)", text)
    return [t.split("#")[0] for t in targets if not re.match(r"^(\w+:|#)", t)]


def link_target(page: Path, target: str) -> Path:
    """The file a link names. The docs hook publishes ``results/`` at the site's root, so a docs
    page's ``results/...`` (seen from ``docs/``) is the repository's ``results/...``."""
    path = (page.parent / target).resolve()
    published = ROOT / "docs" / "results"
    return ROOT / "results" / path.relative_to(published) if path.is_relative_to(published) else path


@functools.cache
def report_files() -> frozenset[str]:
    """The files of the HTML report the docs hook builds into the site's ``report/``."""
    spec = importlib.util.spec_from_file_location("docs_reference_hook", ROOT / "docs" / "hooks" / "reference.py")
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    return frozenset(hook.report_files())


def link_exists(page: Path, target: str) -> bool:
    """Whether a link's target is a file, or a page of the report the docs hook generates."""
    path = link_target(page, target)
    report = ROOT / "docs" / "report"
    return path.relative_to(report).as_posix() in report_files() if path.is_relative_to(report) else path.exists()


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_relative_links_point_at_files_that_exist(page):
    missing = [t for t in relative_links(page.read_text()) if not link_exists(page, t)]
    assert missing == []


def test_the_link_check_sees_links():
    assert relative_links("[a](docs/x.md) `[b](no.md)` [c](https://e.org) [d](#here) ![e](p.png#x)") == ["docs/x.md", "p.png"]


# the commands whose ``--out`` default is computed in code rather than given to the parser (their help says so)
COMPUTED_OUT = {"run": "results/runs/<scene>-<method>", "leaderboard": "results/runs/<suite>"}


def written_paths(args: list[str]) -> list[str]:
    """Where an ``assocbench`` command writes, as given or by default: a file (``-o``/``--output``)
    as is, a folder (``--out``) as a file inside it, so that ``git check-ignore`` sees either."""
    parsed, _ = build_parser().parse_known_args(args)
    output, out = getattr(parsed, "output", None), getattr(parsed, "out", None)
    out = out or (COMPUTED_OUT.get(args[0]) if args else None)
    return [*([output] if output else []), *([f"{out}/any"] if out else [])]


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="not a git checkout")
def test_every_output_the_readme_and_getting_started_write_is_git_ignored():
    """Following the README or the getting-started page in a clone must leave ``git status`` clean:
    ``park.png`` and ``data/ci/`` once were not ignored."""
    commands = [c for page in ("README.md", "docs/getting-started.md") for c in shell_commands((ROOT / page).read_text())]
    paths = sorted({p for c in commands if (args := assocbench_args(c)) for p in written_paths(args)})
    assert {"park.png", "data/ci/any", "frame.png", "o.gif"} <= set(paths)   # the parser sees them
    ignored = subprocess.run(["git", "check-ignore", "--stdin"], input="\n".join(paths), cwd=ROOT,
                             capture_output=True, text=True).stdout.split()
    assert sorted(set(paths) - set(ignored)) == []


def test_written_paths_read_files_folders_and_defaults():
    assert written_paths(["frame", "--scene", "park", "-o", "p.png"]) == ["p.png"]
    assert written_paths(["render", "--method", "jcbb"]) == ["run.mp4"]   # the parser's default
    assert written_paths(["export", "--suite", "ci", "--out", "data/ci"]) == ["data/ci/any"]
    assert written_paths(["run", "--method", "jcbb"]) == ["results/runs/<scene>-<method>/any"]
    assert written_paths(["leaderboard", "--out", "results"]) == ["results/any"]
    assert written_paths(["list"]) == []
