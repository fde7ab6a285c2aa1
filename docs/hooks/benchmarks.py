"""mkdocs hook: the benchmark figures page, made from the records the benchmark scripts write.

``docs/benchmarks.md``'s marker line ``<!-- generated: benchmarks -->`` becomes one section per
benchmark script, grouped and ordered as ``benchmarks/run_all.py`` runs them: what it measures
(its docstring's first paragraph), then for each of its records (``benchmarks/records/*.json``,
written by ``benchmarks/_util.run_recorded``) the command, the lines and tables it printed, and one
line with the commit, date, machine and load. A run without a record yet shows the command that
makes it. A record that lacks a field, or whose field has the wrong type, stops the build with one
line naming the file and the field. ``tests/docs/test_benchmark_records.py`` calls these functions
directly, so it needs no mkdocs.
"""

from __future__ import annotations

import ast
import importlib.util
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BENCHMARKS = ROOT / "benchmarks"
RECORDS = BENCHMARKS / "records"
MARKER = "<!-- generated: benchmarks -->"

NUMBER = (int, float)
OPTIONAL_NUMBER = (int, float, type(None))
# the fields a record must have, with their types; a nested dict is a record's sub-object
FIELDS = {
    "script": str, "command": str, "argv": list, "commit": str, "date": str, "wall_s": NUMBER, "tables": list,
    "machine": {"cpu": str, "cores": OPTIONAL_NUMBER, "ram_gb": OPTIONAL_NUMBER, "os": str, "python": str,
                "libraries": dict},
    "load": {"before": list, "after": list},
}
TABLE_FIELDS = {"caption": str, "headers": list, "rows": list}


class RecordError(ValueError):
    """A record that cannot be shown: its message is one line naming the file and the field."""


def load_record(path: Path) -> dict:
    """The record at ``path``, checked against ``FIELDS``."""
    name = _shown(path)
    try:
        record = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RecordError(f"{name}: not a readable JSON record ({' '.join(str(exc).split())})") from None
    if not isinstance(record, dict):
        raise RecordError(f"{name}: not a JSON object")
    _check(record, FIELDS, name, "")
    if not record["tables"]:
        raise RecordError(f"{name}: field 'tables' is empty")
    for k, table in enumerate(record["tables"]):
        _check(table, TABLE_FIELDS, name, f"tables[{k}].")
        for r, row in enumerate(table["rows"]):
            if not isinstance(row, list) or len(row) != len(table["headers"]):
                raise RecordError(f"{name}: field 'tables[{k}].rows[{r}]' is not a row of "
                                  f"{len(table['headers'])} cells, one per header")
    stem = path.name.split(".")[0]
    if record["script"] != f"{stem}.py" or not (BENCHMARKS / record["script"]).is_file():
        raise RecordError(f"{name}: field 'script' is {record['script']!r}, but the file is named for "
                          f"benchmarks/{stem}.py" + ("" if (BENCHMARKS / f"{stem}.py").is_file() else ", which does not exist"))
    return record


def _check(obj: dict, fields: dict, name: str, prefix: str) -> None:
    if not isinstance(obj, dict):
        raise RecordError(f"{name}: field '{prefix.rstrip('.')}' is not an object")
    for key, kind in fields.items():
        if key not in obj:
            raise RecordError(f"{name}: missing field '{prefix}{key}'")
        if isinstance(kind, dict):
            _check(obj[key], kind, name, f"{prefix}{key}.")
        elif not isinstance(obj[key], kind) or isinstance(obj[key], bool):
            raise RecordError(f"{name}: field '{prefix}{key}' is {type(obj[key]).__name__}, not {_kind(kind)}")


def _kind(kind) -> str:
    names = [k.__name__ for k in (kind if isinstance(kind, tuple) else (kind,))]
    return " or ".join("null" if n == "NoneType" else n for n in names)


def _shown(path: Path) -> str:
    path = Path(path).resolve()
    return path.relative_to(ROOT).as_posix() if path.is_relative_to(ROOT) else str(path)


def load_records(folder: Path = RECORDS) -> dict[str, dict]:
    """Every record in ``folder`` by file name, each checked."""
    return {path.name: load_record(path) for path in sorted(Path(folder).glob("*.json"))}


def _run_all():
    """``benchmarks/run_all.py`` (its ``TOPICS`` and ``NOT_RUN``), loaded from its file."""
    spec = importlib.util.spec_from_file_location("benchmarks_run_all", BENCHMARKS / "run_all.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module   # its dataclass looks its module up while it is made
    spec.loader.exec_module(module)
    return module


def about(script: str) -> str:
    """What a script measures: its docstring's first paragraph, up to a ``Usage:`` line."""
    doc = ast.get_docstring(ast.parse((BENCHMARKS / script).read_text())) or ""
    return " ".join(doc.split("\n\n")[0].split("Usage:")[0].split())


def benchmarks_markdown(folder: Path = RECORDS) -> str:
    """The page's generated part: each group of run_all.py's runs, then the scripts it does not
    run, then any other record; every record in ``folder`` is shown once."""
    records, run_all = load_records(folder), _run_all()
    out, shown = [], set()
    groups = {topic: [(run.script, run.record, run.command()) for run in group] for topic, group in run_all.TOPICS.items()}
    groups["Not run by run_all.py"] = [(script, None, None) for script in run_all.NOT_RUN]
    for topic, planned in groups.items():
        out += [f"## {topic}", ""]
        for script in dict.fromkeys(s for s, _, _ in planned):
            out += [f"### `{script}`", "", _prose(about(script)), ""]
            if script in run_all.NOT_RUN:
                out += [f"Not run by `run_all.py`: {run_all.NOT_RUN[script]}.", ""]
            mine = [(name, command) for s, name, command in planned if s == script and name]
            mine += [(name, None) for name in records if name.split(".")[0] == script[:-3] and
                     name not in {n for n, _ in mine}]
            for name, command in mine:
                out += record_markdown(records[name]) if name in records else \
                    [f"No record yet: `{command}` writes it.", ""]
                shown.add(name)
    rest = [name for name in records if name not in shown]
    if rest:
        out += ["## Other records", ""] + [line for name in rest for line in record_markdown(records[name])]
    return "\n".join(out)


def record_markdown(record: dict) -> list[str]:
    """One record: its command, what it printed (text and tables) and where and when it ran."""
    out = ["```bash", record["command"], "```", ""]
    for table in record["tables"]:
        out += _text(table["caption"])
        out += ["| " + " | ".join(_cell(h) for h in table["headers"]) + " |", "|" + "---|" * len(table["headers"])]
        out += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in table["rows"]] + [""]
    out += _text(record.get("notes", ""))
    return out + [provenance(record), ""]


def provenance(record: dict) -> str:
    """The line under a record: commit, date, machine, load, and how long the run took."""
    m, load = record["machine"], record["load"]
    libraries = ", ".join(f"{name} {version}" for name, version in m["libraries"].items())
    ram = f", {m['ram_gb']} GB RAM" if m["ram_gb"] is not None else ""
    return (f"*Commit `{record['commit']}`, {record['date'].replace('T', ' ').replace('+00:00', ' UTC')}; "
            f"{_escape(m['cpu'])}, {m['cores']} cores{ram}, {_escape(m['os'])}; Python {m['python']}, "
            f"{_escape(libraries)}; load {_load(load['before'])} before, {_load(load['after'])} after; "
            f"{record['wall_s']:.0f} s in all.*")


def _load(values: list) -> str:
    """The one-minute load average of ``os.getloadavg()``'s three."""
    return f"{values[0]:.2f}" if values else "unknown"


def _text(text: str) -> list[str]:
    """Printed lines as Markdown paragraphs, one a line (a printed Markdown heading's ``#`` dropped)."""
    return [line for raw in text.splitlines() if raw.strip() for line in (_prose(raw.strip().lstrip("#").strip()), "")]


def _prose(text: str) -> str:
    """``text`` as Markdown: its code spans (``x`` or `x`) kept as code, Markdown characters elsewhere escaped."""
    parts = re.split(r"(``[^`]+``|`[^`]+`)", text)
    return "".join(f"`{part.strip('`')}`" if k % 2 else _escape(part) for k, part in enumerate(parts))


def _escape(text: str) -> str:
    return re.sub(r"([\\`*_\[\]<>|#])", r"\\\1", text)


def _cell(value) -> str:
    return str(value).replace("|", "\\|").replace("\n", " ")


def on_page_markdown(markdown: str, page, config, files) -> str:
    """Replace the marker with the records; a bad record stops the build with its one line."""
    if MARKER not in markdown:
        return markdown
    try:
        return markdown.replace(MARKER, benchmarks_markdown())
    except RecordError as exc:
        from mkdocs.exceptions import PluginError

        raise PluginError(str(exc)) from None
