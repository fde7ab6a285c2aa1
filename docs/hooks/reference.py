"""mkdocs hook: the reference pages are generated from the code at build time, so they cannot go stale.

A page asks for a generated part with a marker line, replaced in ``on_page_markdown``:

* ``<!-- generated: associators -->``: every registered associator (the registry, plugins
  included): name, kind, summary, and each parameter's type, default and range, read from the
  dataclass fields and their ``assocbench.validation`` metadata (``in_range`` / ``one_of``);
* ``<!-- generated: settings -->``: every setting of every registered track, from its schema
  (``assocbench.harness.config.run_schema(track).describe()``): the tracks that have it, its
  default, what it accepts (its field's ``in_range`` / ``one_of`` metadata), its unit and its
  meaning (its dataclass docstring's ``name: text`` lines);
* ``<!-- generated: cli -->``: every command and option of ``assocbench.cli.main.build_parser()``;
* ``<!-- generated: gym_envs -->``: every registered Gymnasium env id (``assocbench.gymenv.env_ids()``,
  from the track registry): track, scene, open or closed loop.

``on_files`` publishes the committed reference results (``results/``) into the site, so the
benchmark pages can link to their tables and pictures, and the HTML leaderboard that
``assocbench report`` builds from them under ``report/`` (``REPORT_SUITES``, each where present). ``tests/docs/test_docs.py`` imports this
file to check that the generated pages list every method and every setting.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
# the committed leaderboards the site's report is built from, in its order (a missing one is skipped)
REPORT_SUITES = ("results", "results/loop", "results/planar", "results/lines", "results/dense", "results/real/photos",
                 "results/real/victoria", "results/real/victoria_open")
MARKER = re.compile(r"^<!-- generated: (\w+) -->$", re.M)


def _range_text(meta: dict) -> str:
    """A field's accepted values in words, from its ``in_range`` / ``one_of`` metadata."""
    from assocbench.validation import describe_range

    if "choices" in meta:
        return "one of " + ", ".join(f"`{c}`" for c in meta["choices"])
    if "range" in meta:
        text = describe_range(*meta["range"])
        return "" if text == "finite" else text
    return ""


def _cell(text) -> str:
    """``text`` made safe for one Markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _default_text(value) -> str:
    return "`null`" if value is None else f"`{value!r}`" if isinstance(value, str) else f"`{value}`"


def associator_rows() -> list[dict]:
    """One row per registered associator: built-ins, then entry-point plugins."""
    from assocbench.associators.dense import DenseAssociator
    from assocbench.associators.registry import associator_class, available

    rows = []
    for name, summary in available().items():
        try:
            cls = associator_class(name)
        except Exception as exc:  # noqa: BLE001 - a broken plugin is listed with its reason
            rows.append({"name": name, "kind": "?", "summary": f"{summary} ({exc})", "params": []})
            continue
        params = []
        if dataclasses.is_dataclass(cls):
            for f in dataclasses.fields(cls):
                default = f.default if f.default is not dataclasses.MISSING else "(required)"
                params.append({"name": f.name, "type": str(f.type), "default": default,
                               "range": _range_text(dict(f.metadata))})
        kind = "dense" if isinstance(cls, type) and issubclass(cls, DenseAssociator) else "feature"
        rows.append({"name": name, "kind": kind, "summary": summary, "params": params})
    return rows


def associators_markdown() -> str:
    """The associator table: name, kind, summary, parameters with type, default and range."""
    lines = ["| name | kind | what it does | parameters: type = default (range) |", "|---|---|---|---|"]
    for row in associator_rows():
        params = "<br>".join(
            f"`{p['name']}`: {p['type']} = {_default_text(p['default'])}" + (f" ({p['range']})" if p["range"] else "")
            for p in row["params"]) or "none"
        lines.append(f"| `{row['name']}` | {row['kind']} | {_cell(row['summary'])} | {_cell(params)} |")
    return "\n".join(lines) + "\n"


def setting_rows() -> dict[str, tuple]:
    """Every setting of every registered track, once: ``{dotted key: (Described, [tracks])}`` in
    the order the schemas give them (``harness.config.run_schema(track).describe()``)."""
    from assocbench.harness.config import run_schema
    from assocbench.tracks.registry import iter_tracks

    rows: dict[str, tuple] = {}
    for track in iter_tracks():
        for described in run_schema(track).describe():
            rows.setdefault(described.key, (described, []))[1].append(track.name)
    return rows


def setting_keys() -> list[str]:
    """Every setting key of every track, dotted (``belief.sigma_position``); free-form mappings
    (``params``, ``trajectory_params``) are one key each."""
    return list(setting_rows())


def settings_markdown() -> str:
    """The settings reference: the top-level settings, then one table per section, each setting
    with the tracks that have it, its default, what it accepts (range or choices), unit and meaning."""
    from assocbench.tracks.registry import iter_tracks

    every = [track.name for track in iter_tracks()]
    groups: dict[str, list] = {}
    for key, row in setting_rows().items():
        groups.setdefault(key.partition(".")[0] if "." in key else "", []).append(row)
    out = []
    for section, rows in groups.items():
        tracks = list(dict.fromkeys(t for _, owners in rows for t in owners))
        used = "every track" if tracks == every else "the " + ", ".join(tracks) + f" track{'s' if len(tracks) > 1 else ''}"
        out += ["", "## Top-level settings" if not section else f"## `{section}`", "", f"Used by {used}.", "",
                "| key | tracks | default | accepts | unit | meaning |", "|---|---|---|---|---|---|"]
        for described, owners in rows:
            where = "every track" if owners == every else ", ".join(owners)
            out.append(f"| `{described.key}` | {where} | {_cell(_default_text(described.default))} | "
                       f"{_cell(described.accepts)} | {_cell(described.unit)} | {_cell(described.doc)} |")
    return "\n".join(out[1:]) + "\n"


def _option_rows(parser: argparse.ArgumentParser) -> list[str]:
    formatter = parser._get_formatter()
    rows = ["| option | meaning | default |", "|---|---|---|"]
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        names = ", ".join(f"`{s}`" for s in action.option_strings) or f"`{action.dest}` (positional)"
        if action.choices and not isinstance(action, argparse._SubParsersAction):
            names += " {" + ", ".join(map(str, action.choices)) + "}"
        help_text = formatter._expand_help(action) if action.help else ""
        default = "" if action.default in (None, argparse.SUPPRESS, False) or action.required else f"`{action.default}`"
        rows.append(f"| {_cell(names)} | {_cell(help_text)} | {_cell(default)} |")
    return rows


def cli_markdown() -> str:
    """Every command of ``assocbench`` with its usage and options, from the argparse parser."""
    from assocbench.cli.main import build_parser

    parser = build_parser()
    out = []
    for name, sub in parser.commands.items():
        out += [f"## `assocbench {name}`", "", _cell(sub.description or ""), "", "```text",
                sub.format_usage().strip(), "```", ""] + _option_rows(sub) + [""]
    return "\n".join(out)


def gym_envs_markdown() -> str:
    """One row per registered Gymnasium env id: its track, scene (with the scene's description) and loop."""
    from assocbench.gymenv import env_ids
    from assocbench.tracks.registry import get_track

    out = ["| id | track | scene | loop |", "|---|---|---|---|"]
    for env_id, (track, env) in env_ids().items():
        about = get_track(track).scenes().get(env.scene, "")
        loop = "closed" if env.loop else "open"
        out.append(f"| `{env_id}` | {track} | `{env.scene}`: {_cell(about)} | {loop} |")
    return "\n".join(out)


GENERATORS = {"associators": associators_markdown, "settings": settings_markdown, "cli": cli_markdown,
              "gym_envs": gym_envs_markdown}


def on_page_markdown(markdown: str, page, config, files) -> str:
    """Replace each ``<!-- generated: NAME -->`` line with the generated Markdown (a NAME this hook
    does not generate is another hook's: ``benchmarks`` is ``docs/hooks/benchmarks.py``'s)."""
    return MARKER.sub(lambda m: GENERATORS[m.group(1)]() if m.group(1) in GENERATORS else m.group(0), markdown)


def on_files(files, config):
    """Publish the committed reference results (tables and pictures under ``results/``, not
    ``results/runs/``) into the site under ``results/``."""
    from mkdocs.structure.files import File

    for path in sorted((ROOT / "results").rglob("*")):
        rel = path.relative_to(ROOT / "results")
        if path.is_file() and rel.parts[0] != "runs" and path.suffix in {".md", ".png", ".csv"}:
            files.append(File(f"results/{rel.as_posix()}", str(ROOT), config["site_dir"], config["use_directory_urls"]))
    for rel, data in report_files().items():
        files.append(File.generated(config, f"report/{rel}", content=data))
    return files


def report_files() -> dict[str, bytes]:
    """The HTML leaderboard of the committed results (``assocbench report`` of ``REPORT_SUITES``)."""
    from assocbench.harness.report import build_report

    present = [name for name in REPORT_SUITES if (ROOT / name / "leaderboard.csv").is_file()]
    return build_report([ROOT / name for name in present], names=present)
