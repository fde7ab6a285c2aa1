"""Shared helpers of the benchmark scripts: robust timing, plain-text tables, and each run's record.

A script that states a figure ends with ``run_recorded(main)``. Its run then leaves, besides what
it prints, a record ``benchmarks/records/<script>.json`` (``<script>.<name>.json`` with
``--record-as NAME``): every table ``print_table`` / ``print_markdown`` printed (headers, rows and
the lines printed before it), the lines printed after the last table, the command line, the git
commit (``+dirty`` when the checkout differs from it), the UTC date, the machine (CPU model,
cores, RAM, OS, Python and the numeric libraries' versions), the load average before and after
and the wall time. The record is written atomically and only when ``main`` returns success
having printed a table; ``--no-record`` or ``ASSOCBENCH_NO_RECORD=1`` skips it, and
``ASSOCBENCH_RECORDS=DIR`` writes it elsewhere. ``docs/hooks/benchmarks.py`` makes
``docs/benchmarks.md`` from the records.
"""

from __future__ import annotations

import io
import json
import os
import platform
import re
import shlex
import subprocess
import sys
import time
from collections.abc import Callable
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core, as the targets are stated

import numpy as np  # noqa: E402


def time_call(fn: Callable[[], object], repeat: int = 1) -> float:
    """Best-of-``repeat`` wall time of one call, seconds."""
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def timed(fn: Callable[[], object], runs: int, warmup: int) -> list[float]:
    """Wall times (s) of ``runs`` calls of ``fn`` after ``warmup`` untimed ones."""
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(runs):
        start = time.perf_counter()
        fn()
        out.append(time.perf_counter() - start)
    return out


def summary_ms(seconds: list[float]) -> tuple[float, float]:
    """(median, p95) in milliseconds."""
    ms = np.asarray(seconds) * 1e3
    return float(np.median(ms)), float(np.percentile(ms, 95))


def print_table(headers: list[str], rows: list[list[object]]) -> None:
    """Print a right-aligned plain-text table (floats to 3 decimals); the record keeps its cells."""
    headers = [str(h) for h in headers]
    cells = [[f"{c:.3f}" if isinstance(c, float) else str(c) for c in row] for row in rows]
    widths = [max([len(h), *(len(r[k]) for r in cells)]) for k, h in enumerate(headers)]   # no rows: the headers'
    lines = ["  ".join(h.rjust(w) for h, w in zip(headers, widths))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cells]
    _print_recorded(headers, cells, lines + [""])


def print_markdown(text: str) -> None:
    """Print Markdown as it is; the record keeps each of its tables (``| a | b |`` rows under a
    ``|---|`` line) as headers and rows, and the other lines as the text around them."""
    lines = text.splitlines()
    k = 0
    while k < len(lines):
        if _is_row(lines[k]) and k + 1 < len(lines) and re.fullmatch(r"\|(\s*:?-+:?\s*\|)+", lines[k + 1].strip()):
            end = k + 2
            while end < len(lines) and _is_row(lines[end]):
                end += 1
            _print_recorded(_cells(lines[k]), [_cells(row) for row in lines[k + 2:end]], lines[k:end])
            k = end
        else:
            print(lines[k])
            k += 1


def _is_row(line: str) -> bool:
    return line.strip().startswith("|")


def _cells(line: str) -> list[str]:
    """A Markdown table row's cells (an escaped ``\\|`` stays in its cell)."""
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]


def _print_recorded(headers: list[str], rows: list[list[str]], lines: list[str]) -> None:
    """Print a table's ``lines``; in a recorded run, add it to the record with the text printed since
    the previous table as its caption."""
    record = _current
    caption = record.printed_since_table() if record else ""
    for line in lines:
        print(line)
    if record:
        record.add_table(caption, headers, rows)


# --- the record of a run ---------------------------------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]
# distributions whose version can change a figure (those installed are recorded)
LIBRARIES = ("numpy", "scipy", "numba", "llvmlite", "mujoco", "opencv-python-headless", "opencv-python", "pandas",
             "pyarrow", "matplotlib", "scikit-learn", "gtsam", "open3d", "small_gicp")


class _Record:
    """What a recorded run printed, table by table, and the load when it started."""

    def __init__(self) -> None:
        self.out = io.StringIO()
        self.mark = 0
        self.tables: list[dict] = []
        self.load_before = [round(x, 2) for x in os.getloadavg()]
        self.start = time.perf_counter()

    def printed_since_table(self) -> str:
        return self.out.getvalue()[self.mark:].strip()

    def add_table(self, caption: str, headers: list[str], rows: list[list[str]]) -> None:
        self.tables.append({"caption": caption, "headers": headers, "rows": rows})
        self.mark = len(self.out.getvalue())


class _Tee(io.TextIOBase):
    """stdout as it was, with a copy of everything written to it."""

    def __init__(self, stream, copy: io.StringIO) -> None:
        self.stream, self.copy = stream, copy

    def write(self, text: str) -> int:
        self.copy.write(text)
        return self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()

    def isatty(self) -> bool:
        return self.stream.isatty()

    def fileno(self) -> int:
        return self.stream.fileno()


_current: _Record | None = None


def run_recorded(main: Callable[[], int | None]) -> None:
    """Run a benchmark's ``main`` (which reads ``sys.argv``) and exit with its code; on success,
    with a table printed, write the run's record (see the module docstring)."""
    global _current
    argv = list(sys.argv)
    rest, name, skip = _record_options(argv[1:])
    sys.argv = [argv[0], *rest]
    if skip:
        sys.exit(main())
    _current = record = _Record()
    stdout, sys.stdout = sys.stdout, _Tee(sys.stdout, record.out)
    try:
        code = main()
    finally:
        sys.stdout, _current = stdout, None
    if code in (None, 0) and record.tables:
        path = records_dir() / f"{Path(argv[0]).stem}{'.' + name if name else ''}.json"
        write_record(path, record_of(record, argv))
        print(f"record: {path}", file=sys.stderr)
    sys.exit(code)


def _record_options(args: list[str]) -> tuple[list[str], str, bool]:
    """``args`` without ``--no-record`` and ``--record-as NAME``; NAME (or ""); whether to skip."""
    skip = os.environ.get("ASSOCBENCH_NO_RECORD", "") not in ("", "0") or "--no-record" in args
    rest, name = [a for a in args if a != "--no-record"], ""
    if "--record-as" in rest:
        k = rest.index("--record-as")
        name = rest[k + 1] if k + 1 < len(rest) else ""
        if not re.fullmatch(r"[a-z0-9_-]+", name):
            sys.exit(f"{Path(sys.argv[0]).name}: error: --record-as takes a name of a-z, 0-9, _ and -, got {name!r}")
        del rest[k:k + 2]
    return rest, name, skip


def records_dir() -> Path:
    """Where records go: ``$ASSOCBENCH_RECORDS`` or ``benchmarks/records``."""
    return Path(os.environ.get("ASSOCBENCH_RECORDS") or ROOT / "benchmarks" / "records")


def record_of(record: _Record, argv: list[str]) -> dict:
    """The record of a finished run started with ``argv``."""
    script = Path(argv[0]).resolve()
    shown = script.relative_to(ROOT).as_posix() if script.is_relative_to(ROOT) else str(script)
    return {"script": script.name, "command": shlex.join(["python", shown, *argv[1:]]), "argv": argv[1:],
            "commit": git_commit(), "date": datetime.now(UTC).isoformat(timespec="seconds"),
            "machine": machine(), "load": {"before": record.load_before,
                                           "after": [round(x, 2) for x in os.getloadavg()]},
            "wall_s": round(time.perf_counter() - record.start, 1), "tables": record.tables,
            "notes": record.printed_since_table()}


def write_record(path: Path, record: dict) -> None:
    """Write ``record`` as JSON to ``path`` atomically: a temporary file beside it, then a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(json.dumps(record, indent=1, ensure_ascii=False) + "\n")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def git_commit() -> str:
    """The checkout's short commit, ``+dirty`` when a file differs from it (records aside), or
    ``unknown`` outside a git checkout."""
    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()

    try:
        commit = git("rev-parse", "--short", "HEAD")
        dirty = git("status", "--porcelain", "--", ".", ":(exclude)benchmarks/records")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return commit + ("+dirty" if dirty else "")


def machine() -> dict:
    """The CPU model, logical cores, RAM, OS, Python and the installed ``LIBRARIES``' versions."""
    libraries = {}
    for name in LIBRARIES:
        try:
            libraries[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            pass
    return {"cpu": _proc_field("/proc/cpuinfo", "model name") or platform.processor() or "unknown",
            "cores": os.cpu_count(), "ram_gb": _ram_gb(), "os": _os_name(),
            "python": platform.python_version(), "libraries": libraries}


def _proc_field(path: str, key: str) -> str:
    """The first ``key: value`` line's value of a /proc-style file, or ""."""
    try:
        for line in Path(path).read_text().splitlines():
            name, _, value = line.partition(":")
            if name.strip() == key:
                return value.strip()
    except OSError:
        pass
    return ""


def _ram_gb() -> float | None:
    total = _proc_field("/proc/meminfo", "MemTotal").split()
    return round(int(total[0]) / 2**20, 1) if total else None


def _os_name() -> str:
    """The distribution's name (``/etc/os-release``) and the kernel, e.g. ``Debian GNU/Linux 12 (Linux 6.1.0)``."""
    try:
        name = platform.freedesktop_os_release().get("PRETTY_NAME", "")
    except OSError:
        name = ""
    return f"{name or platform.system()} ({platform.system()} {platform.release()})"
