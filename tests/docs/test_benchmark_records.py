"""Benchmark records: a benchmark script that prints a table leaves a record of it (command, commit,
date, machine, load), docs/benchmarks.md is generated from every record, and a record missing a
field is refused in one line naming the file and the field. The generator is the mkdocs hook
``docs/hooks/benchmarks.py``; these tests call it directly, so they need no mkdocs."""

from __future__ import annotations

import copy
import importlib.util
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BENCHMARKS = ROOT / "benchmarks"
TABLE_SCRIPT = """
import sys
from _util import print_markdown, print_table, run_recorded

def main():
    print("a caption")
    print_table(["n", "ms"], [[10, 0.5], [20, 1.25]])
    print_markdown("### second\\n| a | b \\\\| c |\\n|---|---|\\n| x | y |\\n")
    print("a note")
    return int(sys.argv[1]) if sys.argv[1:] else 0

run_recorded(main)
"""


def load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def hook():
    return load(ROOT / "docs" / "hooks" / "benchmarks.py", "docs_benchmarks_hook")


def run_script(tmp_path: Path, *args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """``TABLE_SCRIPT`` saved as ``benchmarks/jcbb_anytime.py``'s twin in ``tmp_path`` (beside a copy
    of ``_util.py``), run with records going to ``tmp_path/records``."""
    (tmp_path / "_util.py").write_text((BENCHMARKS / "_util.py").read_text())
    (tmp_path / "jcbb_anytime.py").write_text(TABLE_SCRIPT)
    environ = {k: v for k, v in os.environ.items() if k != "ASSOCBENCH_NO_RECORD"}
    environ.update(ASSOCBENCH_RECORDS=str(tmp_path / "records"), **(env or {}))
    return subprocess.run([sys.executable, str(tmp_path / "jcbb_anytime.py"), *args], env=environ,
                          capture_output=True, text=True, timeout=60)


def test_a_recorded_run_keeps_its_tables_command_commit_machine_and_load(tmp_path, hook):
    done = run_script(tmp_path, "0")
    assert done.returncode == 0, done.stderr
    record = json.loads((tmp_path / "records" / "jcbb_anytime.json").read_text())
    assert [t["caption"] for t in record["tables"]] == ["a caption", "### second"]
    assert record["tables"][0]["headers"] == ["n", "ms"] and record["tables"][0]["rows"] == [["10", "0.500"], ["20", "1.250"]]
    assert record["tables"][1]["headers"] == ["a", "b | c"] and record["tables"][1]["rows"] == [["x", "y"]]
    assert record["notes"] == "a note" and record["argv"] == ["0"] and record["command"].endswith("jcbb_anytime.py 0")
    assert set(record["machine"]) >= {"cpu", "cores", "ram_gb", "os", "python", "libraries"}
    assert "numpy" in record["machine"]["libraries"] and len(record["load"]["before"]) == 3
    assert record["date"].endswith("+00:00") and record["commit"]
    assert "a caption" in done.stdout and "| a | b \\| c |" in done.stdout   # printed as before
    assert [p.name for p in (tmp_path / "records").iterdir()] == ["jcbb_anytime.json"]   # no temporary file left
    hook.load_record(tmp_path / "records" / "jcbb_anytime.json")   # what the writer writes, the page reads


def test_no_record_for_a_failed_run_or_when_asked_not_to(tmp_path):
    assert run_script(tmp_path, "3").returncode == 3
    assert run_script(tmp_path, "0", "--no-record").returncode == 0
    assert run_script(tmp_path, "0", env={"ASSOCBENCH_NO_RECORD": "1"}).returncode == 0
    assert not (tmp_path / "records").exists()


def test_record_as_names_a_second_record_and_refuses_a_bad_name_in_one_line(tmp_path):
    assert run_script(tmp_path, "0", "--record-as", "bays").returncode == 0
    record = json.loads((tmp_path / "records" / "jcbb_anytime.bays.json").read_text())
    assert record["argv"] == ["0", "--record-as", "bays"]   # the command that makes this very record
    bad = run_script(tmp_path, "--record-as", "Bad Name")
    assert bad.returncode == 1 and bad.stderr.strip().count("\n") == 0 and "--record-as" in bad.stderr


def test_the_commit_says_dirty_when_the_checkout_differs(tmp_path, monkeypatch):
    util = load(BENCHMARKS / "_util.py", "benchmarks_util")
    repo = tmp_path / "repo"
    (repo / "benchmarks" / "records").mkdir(parents=True)
    git = ["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run([*git, "init", "-q"], check=True)
    (repo / "a.txt").write_text("a")
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "a"], check=True)
    monkeypatch.setattr(util, "ROOT", repo)
    assert not util.git_commit().endswith("+dirty")
    (repo / "benchmarks" / "records" / "x.json").write_text("{}")   # a record is not a change of the code
    assert not util.git_commit().endswith("+dirty")
    (repo / "a.txt").write_text("b")
    assert util.git_commit().endswith("+dirty")


def a_record(hook, tmp_path: Path, name: str = "jcbb_anytime.json") -> Path:
    """A valid record, as ``run_recorded`` writes it, in ``tmp_path``."""
    assert run_script(tmp_path, "0").returncode == 0
    record = json.loads((tmp_path / "records" / "jcbb_anytime.json").read_text())
    record["script"] = name.split(".")[0] + ".py"
    path = tmp_path / "records" / name
    path.write_text(json.dumps(record))
    return path


def dotted_fields(hook) -> list[str]:
    """Every required field of a record, dotted (``machine.cpu``), and of its first table."""
    out = []
    for key, kind in hook.FIELDS.items():
        out += [f"{key}.{sub}" for sub in kind] if isinstance(kind, dict) else [key]
    return out + [f"tables[0].{key}" for key in hook.TABLE_FIELDS]


def test_a_record_missing_a_field_is_refused_in_one_line_naming_file_and_field(tmp_path, hook):
    path = a_record(hook, tmp_path)
    good = json.loads(path.read_text())
    fields = dotted_fields(hook)
    assert {"commit", "date", "argv", "machine.cpu", "machine.libraries", "load.before", "load.after",
            "tables[0].headers", "tables[0].rows"} <= set(fields)
    for field in fields:
        record = copy.deepcopy(good)
        *parents, last = field.replace("[0]", ".0").split(".")
        holder = record
        for part in parents:
            holder = holder[int(part)] if part.isdigit() else holder[part]
        del holder[last]
        path.write_text(json.dumps(record))
        with pytest.raises(hook.RecordError) as err:
            hook.benchmarks_markdown(path.parent)
        message = str(err.value)
        assert "\n" not in message and message.startswith(str(path)) and f"'{field}'" in message, message


@pytest.mark.parametrize("change, said", [
    (lambda r: r["machine"].update(cores="two"), "'machine.cores' is str"),
    (lambda r: r["tables"][0]["rows"].append(["1"]), "'tables[0].rows[2]' is not a row of 2 cells"),
    (lambda r: r.update(tables=[]), "'tables' is empty"),
    (lambda r: r.update(script="other.py"), "'script' is 'other.py'"),
])
def test_a_record_with_a_bad_field_is_refused_in_one_line(tmp_path, hook, change, said):
    path = a_record(hook, tmp_path)
    record = json.loads(path.read_text())
    change(record)
    path.write_text(json.dumps(record))
    with pytest.raises(hook.RecordError, match=re.escape(said)) as err:
        hook.load_record(path)
    assert "\n" not in str(err.value)


def test_the_page_lists_every_record_with_its_command_table_and_provenance(tmp_path, hook):
    first = a_record(hook, tmp_path)
    a_record(hook, tmp_path, "dense_flat.bays.json")
    a_record(hook, tmp_path, "dense_fusion_ab.json")   # a script run_all.py does not run
    page = hook.benchmarks_markdown(first.parent)
    records = hook.load_records(first.parent)
    assert len(records) == 3
    for record in records.values():
        assert f"```bash\n{record['command']}\n```" in page
        assert f"*Commit `{record['commit']}`" in page
    assert page.count("| n | ms |") == 3 and "| 10 | 0.500 |" in page and "| a | b \\| c |" in page
    assert "No record yet: `python benchmarks/jcbb_vs_textbook.py` writes it." in page
    assert "a caption" in page and "a note" in page and "### second" not in page


def test_the_page_lists_every_committed_record(hook):
    page = hook.benchmarks_markdown()
    for record in hook.load_records().values():
        assert f"```bash\n{record['command']}\n```" in page


def recording_scripts() -> set[str]:
    return {p.name for p in BENCHMARKS.glob("*.py") if p.name != "_util.py" and "run_recorded(main)" in p.read_text()}


def test_every_script_that_prints_a_table_records_it_and_run_all_runs_it_or_says_why_not():
    run_all = load(BENCHMARKS / "run_all.py", "benchmarks_run_all")
    printing = {p.name for p in BENCHMARKS.glob("*.py") if p.name != "_util.py" and
                ("print_table(" in p.read_text() or "print_markdown(" in p.read_text())}
    assert printing and printing <= recording_scripts()
    planned = {run.script for run in run_all.runs()}
    assert planned | set(run_all.NOT_RUN) == recording_scripts() and not planned & set(run_all.NOT_RUN)
    assert len({run.record for run in run_all.runs()}) == len(run_all.runs())   # no two runs share a record


def test_the_association_compile_notice_announces_what_first_run_measured():
    """The notice's "~N s" is a measurement: within a factor 2 of benchmarks/first_run.py's record."""
    from assocbench import kernels

    path = BENCHMARKS / "records" / "first_run.json"
    if not path.is_file():
        pytest.skip("benchmarks/records/first_run.json not recorded yet (python benchmarks/run_all.py --only first_run)")
    rows = {row[0]: row for row in json.loads(path.read_text())["tables"][0]["rows"]}
    measured = float(rows["association kernels, jcbb"][2])
    assert measured / 2 <= kernels.ASSOCIATION_COMPILE_S <= measured * 2, (measured, kernels.ASSOCIATION_COMPILE_S)
