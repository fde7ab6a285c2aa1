"""The README's test command runs the default set; the slow set (``@pytest.mark.slow``) is left out of
it, runs with ``-m slow``, and CI (``.ci/run``) runs it after the default set, failing on it too."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SLOW_FILE = "tests/cli/test_install.py"   # one slow test and one that is not; collects fast
INSTALL = f"{SLOW_FILE}::test_fresh_venv_pip_install_then_assocbench_run"


def collected(*args: str) -> list[str]:
    """The node ids ``pytest --collect-only`` selects from ``SLOW_FILE`` with ``args``."""
    proc = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
                           *args, SLOW_FILE], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode in (0, 5), proc.stdout + proc.stderr   # 5: nothing selected
    return [line for line in proc.stdout.splitlines() if "::" in line]


def test_the_slow_marker_is_registered_and_left_out_by_default():
    options = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert any(m.startswith("slow:") for m in options["markers"])
    assert "--strict-markers" in options["addopts"]   # a misspelt mark fails instead of running by default


def test_the_default_run_deselects_the_slow_set_and_dash_m_slow_selects_it():
    default = collected()
    assert default and INSTALL not in default   # the file's other test still runs by default
    assert collected("-m", "slow") == [INSTALL]


def test_ci_runs_the_slow_set_after_the_default_set_and_fails_on_it():
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()
             if not line.lstrip().startswith("#")]
    default = next(i for i, line in enumerate(lines) if re.search(r"pytest -q -n auto( &&|$)", line))
    slow = next(i for i, line in enumerate(lines) if "pytest -q -n auto -m slow" in line)
    assert default < slow and lines[slow].endswith("|| exit 1"), lines[slow]


def test_the_readme_and_getting_started_say_how_to_run_the_slow_set_and_that_ci_runs_both():
    for page in ("README.md", "docs/getting-started.md"):
        text = " ".join((ROOT / page).read_text().split())
        assert "`pytest -m slow`" in text and "CI runs both sets" in text, page


def test_no_two_test_files_share_a_name():
    """The tests are folders without ``__init__.py`` (rootdir imports), so two ``test_x.py`` in two
    folders are one module to pytest: the second fails to import ("import file mismatch"), which
    only a run of the whole suite shows. tests/associators/test_registry.py once shadowed
    tests/tracks/test_registry.py."""
    names: dict[str, list[str]] = {}
    for path in sorted((ROOT / "tests").rglob("test_*.py")):
        names.setdefault(path.name, []).append(str(path.relative_to(ROOT)))
    assert {name: paths for name, paths in names.items() if len(paths) > 1} == {}
