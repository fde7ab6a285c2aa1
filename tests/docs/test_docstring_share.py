"""Docstrings say what and why, not how a figure changed: they stay at most a quarter of the
package's characters and no docstring or comment carries measurement history (dates, issue
numbers, "was 18.3 ms", "0.40 against 0.52 ms", ...). Counted by ``tools/docstring_share.py``."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TOOL = ROOT / "tools" / "docstring_share.py"
MAX_SHARE = 0.25


@pytest.fixture(scope="module")
def share():
    spec = importlib.util.spec_from_file_location("docstring_share", TOOL)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module   # its dataclass resolves its annotations through sys.modules
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def counts(share):
    return share.count_package()


def test_docstrings_are_at_most_a_quarter_of_the_package(share, counts):
    assert share.overall_share(counts) <= MAX_SHARE, share.folder_table(counts)["overall"]


def test_no_docstring_or_comment_tells_measurement_history(share, counts):
    assert share.history_hits(counts) == []


def test_the_counter_counts_the_docstring_literal_and_nothing_else(share, tmp_path):
    source = ('"""Module."""\n\n# a comment\n\n\ndef f():\n    """f\'s docstring: ``x = 1``."""\n'
              '    return "not a docstring"\n\n\nclass C:\n    r"""Raw, é."""\n')
    (tmp_path / "m.py").write_text(source, encoding="utf-8")
    [count] = share.count_package(tmp_path)
    literals = ['"""Module."""', '"""f\'s docstring: ``x = 1``."""', 'r"""Raw, é."""']
    assert count.chars == len(source)
    assert count.doc_chars == sum(map(len, literals))
    assert count.comment_chars == len("# a comment")


@pytest.mark.parametrize("text", [
    "# 18.3 ms earlier that day", "took 2 min 5 s on 2026-11-26", "(issue 27)", "a helper measured it",
    "since commit 0e69108", "fusion 14.5 -> 10.6 ms a frame", "0.40 against 0.52 ms for 39 000 pairs",
    "about 3.5 ms a frame", "was 4.8 us", "(load 7, noisy)",
])
def test_history_patterns_catch_a_figure_with_its_past(share, text):
    assert any(rx.search(text) for rx in share.PATTERNS.values()), text


@pytest.mark.parametrize("text", [
    "NIS(A) <= χ²_{d|A|}(c)", "the earlier view's feature", "an 80 x 80 matrix", "every 1.5 m",
    "(``benchmarks/dense_rate.py``)", "a helper function", "time_limit_s: the most one call may take (s)",
])
def test_history_patterns_leave_what_and_why_alone(share, text):
    assert not any(rx.search(text) for rx in share.PATTERNS.values()), text


def test_the_tool_prints_the_table_and_its_history_mode_exits_0():
    table = subprocess.run([sys.executable, str(TOOL)], capture_output=True, text=True, timeout=120, check=True)
    assert table.stdout.splitlines()[-1].startswith("overall")
    history = subprocess.run([sys.executable, str(TOOL), "--history"], capture_output=True, text=True, timeout=120)
    assert history.returncode == 0, history.stdout
