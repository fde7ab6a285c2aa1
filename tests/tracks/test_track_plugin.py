"""The add-a-track how-to, followed literally: the example package (``examples/track_plugin``),
copied out of the repository and installed with pip, runs through every command the page lists,
with no ``ASSOCBENCH_TRACKS`` set and no edit to assocbench."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "howto" / "add-track.md"
BIN = Path(sys.executable).parent


def page_commands() -> list[str]:
    """The bash block under the page's "Install it and run it" heading, a command a line."""
    text = PAGE.read_text().split("## Install it and run it", 1)[1]
    block = re.search(r"```bash\n(.*?)```", text, re.S).group(1)
    return [line for line in block.splitlines() if line.strip()]


def as_run_here(command: str, target: Path) -> list[str]:
    """A page command as this test runs it: ``pip install`` into ``target`` (on ``PYTHONPATH``:
    never into the test's own environment), the rest with this environment's executables."""
    words = shlex.split(command)
    if words[:2] == ["pip", "install"]:
        return [sys.executable, "-m", "pip", "install", "-q", "--no-build-isolation", "--target", str(target), *words[2:]]
    if words[0] == "python":
        return [sys.executable, *words[1:]]
    return [str(BIN / words[0]), *words[1:]]


@pytest.fixture(scope="module")
def followed(tmp_path_factory):
    """Every command of the page run in a scratch folder: (folder, {command: completed process})."""
    work = tmp_path_factory.mktemp("plugin")
    shutil.copytree(ROOT / "examples" / "track_plugin", work / "track_plugin")
    target = work / "site"
    env = {k: v for k, v in os.environ.items() if k not in ("ASSOCBENCH_TRACKS", "PYTHONPATH")}
    env |= {"PYTHONPATH": str(target), "ASSOCBENCH_CACHE": str(work / "cache")}
    done = {}
    for command in page_commands():
        done[command] = subprocess.run(as_run_here(command, target), cwd=work, env=env, capture_output=True,
                                       text=True, timeout=600)
        assert done[command].returncode == 0, f"{command}: {done[command].stderr[-2000:]}"
    return work, done


def test_the_page_lists_every_command_the_issue_asks_for():
    commands = " ".join(page_commands())
    for what in ("pip install", "assocbench run --track beacons", "assocbench leaderboard", "check --suite beacons_ci "
                 "--update", "assocbench report", "assocbench export", "gymnasium.make"):
        assert what in commands


def test_the_example_track_is_at_most_150_lines_and_names_no_internal_module():
    source = (ROOT / "examples" / "track_plugin" / "beacons" / "__init__.py").read_text()
    assert len(source.splitlines()) <= 150
    assert "ASSOCBENCH_TRACKS" not in source


@pytest.mark.slow   # packaging: pip-installs the example (user tracks: test_toy_track; entry points: tests/plugins.py)
def test_run_leaderboard_check_report_export_and_gym_serve_the_installed_track(followed):
    work, done = followed
    by = {c.split()[1] if c.startswith("assocbench") else c.split()[0]: p for c, p in done.items()}
    assert "beacons" in by["list"].stdout
    assert "on sample (beacons track)" in by["run"].stdout
    assert "ok: 8 scenario × method rows compared" in by["check"].stdout
    card = json.loads((work / "lb" / "leaderboard.json").read_text())
    assert card["track"] == "beacons" and card["primary"] == {"name": "perfect", "higher_better": True,
                                                               "unit": "share of frames"}
    page = (work / "report" / "beacons-open-loop.html").read_text()
    assert "<h1>Beacons, open loop</h1>" in page and "perfect frames" in page
    assert str(work) not in page                       # scenarios by the log's short name, never a path
    assert "sample/recorded" in (work / "lb" / "leaderboard.csv").read_text()
    assert (work / "data" / "problems.parquet").is_file()


@pytest.mark.slow   # needs the installed example (the fixture above)
def test_a_bad_line_in_a_users_log_is_one_line_naming_the_file_and_line(followed):
    work, _ = followed
    log = work / "mine.log"
    log.write_text("L 0 1 0.0 0.0 0.1 0.0 0.1\nZ 0 1 0.0 oops 0.01 0.0 0.01\n")
    env = {k: v for k, v in os.environ.items() if k != "ASSOCBENCH_TRACKS"} | {"PYTHONPATH": str(work / "site")}
    proc = subprocess.run([str(BIN / "assocbench"), "run", "--track", "beacons", "--scene", str(log), "--method",
                           "mnn"], cwd=work, env=env, capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and f"{log} line 2" in proc.stderr
