"""How much of the package's source is docstrings, per folder and overall, and which docstrings or
comments still tell measurement history.

How it counts, for every ``.py`` file under ``assocbench/`` (``__pycache__`` excluded), read as UTF-8:

* a file's characters: ``len`` of its whole text (code, comments, blank lines, docstrings);
* its docstring characters: for each module, class and function (``def`` and ``async def``, nested
  ones included) whose body starts with a string-constant expression, as ``ast.get_docstring``
  finds it, the source span of that string literal, quotes and prefix included, from its first
  to its last character (``lineno``/``col_offset`` to ``end_lineno``/``end_col_offset``);
* its comment characters (shown, not part of the share): every ``#`` comment token's text.

A folder's share is the docstring characters of the ``.py`` files directly in it over their
characters (a subfolder is its own row); the overall share is the same sums over every file.

``--history`` lists instead each docstring or comment that matches one of ``HISTORY`` (dates,
issue numbers, commit hashes, timings with their past: "was 18.3 ms", "took 2 min", "a helper
measured", ...), one line each, ``path:line: pattern: text``; it exits 1 when it lists any.

    python tools/docstring_share.py              # the table
    python tools/docstring_share.py --history    # docstrings and comments that carry history

This is a source scan, not a benchmark: it times nothing, so it lives in ``tools/``, not in
``benchmarks/`` beside the scripts whose figures ``docs/benchmarks.md`` reports.
"""

from __future__ import annotations

import argparse
import ast
import io
import re
import sys
import tokenize
from dataclasses import dataclass, field
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "assocbench"
DOCUMENTED = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)
UNITS = r"ns|µs|us|ms|s|sec|seconds?|min|minutes?|h|hours?"
TIME = rf"(?:{UNITS})\b"
FIGURE = r"(?:about |~|≈ ?)?\d[\d.,]*(?: ?[-–] ?\d[\d.,]*)?"
# what measurement history reads like: when (a date, an issue, a commit), who (a helper), where (a
# loaded core), and a figure with its past or its rival (was, took, earlier, from ... to, against)
HISTORY = {
    "date": r"\b20\d\d-[01]\d(?:-[0-3]\d)?\b",
    "issue number": r"\bissues? #?\d+|(?<![\w&])#\d{2,}\b",
    "commit hash": r"\bcommits? [0-9a-f]{7,40}\b|\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b",
    "helper": r"\bhelpers? (?:measured|found|timed|ran|saw|reported|wrote)\b|\bby a helper\b",
    "was <figure>": r"\b(?:was|were|used to be|used to take) (?:about |~)?\d",
    "took <figure>": r"\btook (?:about |~)?\d",
    "<figure> earlier": rf"\d[\d.,]*\s*(?:%|x|×|{UNITS})?\s+earlier\b|\bearlier (?:that|this) (?:day|week|month)",
    "measured on": r"\bmeasured (?:on|at|in) (?:20\d\d|a |the |this |our |\d)",
    "from <figure> to": rf"\bfrom {FIGURE}\s*(?:{UNITS})?\s*to {FIGURE}\s*{TIME}",
    "<figure> -> <figure>": rf"{FIGURE}\s*(?:{UNITS})?\s*(?:->|→)\s*{FIGURE}\s*{TIME}",
    "<figure> against <figure>": rf"{FIGURE}\s*(?:{UNITS})?\s+(?:against|instead of|vs\.?|versus)\s+{FIGURE}\s*{TIME}",
    "down/up from": r"\b(?:down|up) from (?:about |~)?\d",
    "before the fix": r"\bbefore (?:the|this|that) (?:fix|change|commit|rewrite)\b",
    "machine load": r"\bon (?:a |one )?(?:loaded|quiet|busy) (?:core|machine)|\(load \d|\bone core\)",
    "timing figure": r"\d[\d.,]*\s*(?:ns|µs|us|ms)\b",
}
PATTERNS = {name: re.compile(rx, re.I) for name, rx in HISTORY.items()}


@dataclass
class FileCount:
    path: Path
    chars: int
    doc_chars: int
    comment_chars: int
    texts: list[tuple[int, str, str]] = field(default_factory=list)   # (line, "docstring"/"comment", text)


def _offset(lines: list[str], line: int, col_bytes: int) -> int:
    """Character offset in the file of (1-based ``line``, UTF-8 byte column ``col_bytes``), as ast gives them."""
    before = sum(len(text) for text in lines[:line - 1])
    return before + len(lines[line - 1].encode()[:col_bytes].decode())


def docstring_spans(source: str) -> list[tuple[int, int, int]]:
    """``(start, end, line)`` of every module, class and function docstring literal in ``source``."""
    lines = source.splitlines(keepends=True)
    spans = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, DOCUMENTED) and node.body and isinstance(node.body[0], ast.Expr):
            value = node.body[0].value
            if isinstance(value, ast.Constant) and isinstance(value.value, str):
                spans.append((_offset(lines, value.lineno, value.col_offset),
                              _offset(lines, value.end_lineno, value.end_col_offset), value.lineno))
    return sorted(spans)


def count_file(path: Path) -> FileCount:
    source = path.read_text(encoding="utf-8")
    spans = docstring_spans(source)
    texts = [(line, "docstring", source[start:end]) for start, end, line in spans]
    comments = [tok for tok in tokenize.generate_tokens(io.StringIO(source).readline) if tok.type == tokenize.COMMENT]
    texts += [(tok.start[0], "comment", tok.string) for tok in comments]
    return FileCount(path, len(source), sum(end - start for start, end, _ in spans),
                     sum(len(tok.string) for tok in comments), sorted(texts))


def count_package(root: Path = PACKAGE) -> list[FileCount]:
    return [count_file(p) for p in sorted(root.rglob("*.py")) if "__pycache__" not in p.parts]


def folder_table(counts: list[FileCount], root: Path = PACKAGE) -> dict[str, tuple[int, int, int, int]]:
    """``{folder: (files, chars, docstring chars, comment chars)}``, folders relative to the
    package's parent (``assocbench/tracks/dense``), then ``overall``."""
    rows: dict[str, list[int]] = {}
    for c in counts:
        row = rows.setdefault(c.path.parent.relative_to(root.parent).as_posix(), [0, 0, 0, 0])
        for i, value in enumerate((1, c.chars, c.doc_chars, c.comment_chars)):
            row[i] += value
    rows = dict(sorted(rows.items()))
    rows["overall"] = [sum(r[i] for r in rows.values()) for i in range(4)]
    return {name: tuple(r) for name, r in rows.items()}


def overall_share(counts: list[FileCount]) -> float:
    return sum(c.doc_chars for c in counts) / sum(c.chars for c in counts)


def history_hits(counts: list[FileCount], root: Path = PACKAGE) -> list[str]:
    """``path:line: pattern: text`` for each docstring or comment line that matches a ``HISTORY`` pattern."""
    out = []
    for c in counts:
        for line, _, text in c.texts:
            for i, part in enumerate(text.splitlines()):
                for name, rx in PATTERNS.items():
                    if rx.search(part):
                        out.append(f"{c.path.relative_to(root.parent).as_posix()}:{line + i}: {name}: {part.strip()}")
    return out


def print_table(table: dict[str, tuple[int, int, int, int]]) -> None:
    print(f"{'folder':<32} {'files':>5} {'chars':>9} {'docstrings':>10} {'share':>6} {'comments':>8}")
    for name, (files, chars, doc, comment) in table.items():
        print(f"{name:<32} {files:>5} {chars:>9} {doc:>10} {doc / chars:>6.1%} {comment:>8}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--history", action="store_true", help="list docstrings and comments that tell history")
    args = parser.parse_args(argv)
    counts = count_package()
    if args.history:
        hits = history_hits(counts)
        print("\n".join(hits) if hits else "no measurement history in docstrings or comments")
        return 1 if hits else 0
    print_table(folder_table(counts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
