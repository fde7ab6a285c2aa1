"""mkdocs hook: the reference pages are generated from the code at build time, so they cannot go stale.

A page asks for a generated part with a marker line, replaced in ``on_page_markdown``:

* ``<!-- generated: associators -->``: every registered associator (the registry, plugins
  included): name, kind, summary, and each parameter's type, default and range, read from the
  dataclass fields and their ``assocbench.validation`` metadata (``in_range`` / ``one_of``);
* ``<!-- generated: settings -->``: every run setting: the schema is
  ``assocbench.harness.config.defaults()``; a section's dataclass (``BeliefConfig``,
  ``EstimatorConfig``, each registered track's ``section_types()``) gives the type, range and the
  meaning (its docstring's ``name: text`` lines), ``configs/default.yaml`` the run's default;
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
REPORT_SUITES = ("results", "results/loop", "results/planar", "results/lines", "results/dense", "results/real/victoria",
                 "results/real/victoria_open")
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


def _field_docs(cls: type) -> dict[str, str]:
    """``{field: meaning}`` from the class docstring's ``name: text`` entries (the house style:
    ``sigma_position: camera position std (m).``); a field the docstring does not name is absent."""
    doc = cls.__doc__ or ""
    names = [f.name for f in dataclasses.fields(cls)]
    # ``a / b: text`` names two fields at once: each gets the text after the shared colon
    hits = sorted((m.start(), m.end(), name) for name in names
                  for m in re.finditer(rf"(?<![\w.`]){re.escape(name)}(?:\s*/\s*\w+)*: ", doc))
    out = {}
    for _, end, name in hits:
        stop = min((start for start, _, _ in hits if start >= end), default=len(doc))
        text = re.split(r"\n\s*\n", doc[end:stop])[0]
        out.setdefault(name, " ".join(text.split()))
    return out


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


def _section_classes() -> dict[str, tuple[type, str]]:
    """``{section: (dataclass, owner)}`` for every typed section: the common ones and each track's."""
    from assocbench.belief.config import BeliefConfig
    from assocbench.estimators.config import EstimatorConfig
    from assocbench.tracks.registry import iter_tracks

    out = {"belief": (BeliefConfig, "every track (open loop)"), "estimator": (EstimatorConfig, "every track (closed loop)")}
    for track in iter_tracks():
        for name, cls in track.section_types().items():
            owner = out[name][1] + ", " + track.name if name in out else f"{track.name} track"
            out[name] = (cls, owner)
    return out


def _yaml_comments() -> dict[str, str]:
    """``{dotted key: comment}`` from ``configs/default.yaml``'s end-of-line comments."""
    from assocbench.configs import shipped_config

    out, section = {}, None
    for line in shipped_config("default.yaml").read_text().splitlines():
        m = re.match(r"^(\s*)([\w]+):[^#]*?(?:#\s*(.*))?$", line)
        if not m:
            continue
        indent, key, comment = m.groups()
        if not indent:
            section = key
        dotted = key if not indent else f"{section}.{key}"
        if comment:
            out[dotted] = comment.strip()
    return out


def setting_keys() -> list[str]:
    """Every setting key of a run, dotted (``belief.sigma_position``); free-form mappings
    (``params``, ``trajectory_params``) are one key each."""
    from assocbench.harness.config import defaults

    keys = []
    for name, value in defaults().items():
        if isinstance(value, dict) and value:
            keys += [f"{name}.{k}" for k in value]
        else:
            keys.append(name)
    return keys


def settings_markdown() -> str:
    """The settings reference: the plain settings, then one table per section."""
    from assocbench.harness.config import defaults, merge
    from assocbench.harness.yamlfile import read_yaml, shipped_config

    schema = defaults()
    run_default = merge(defaults(), read_yaml(shipped_config("default.yaml")), "default.yaml")
    comments = _yaml_comments()
    typed = _section_classes()
    out = ["## Plain settings", "", "| key | default | meaning |", "|---|---|---|"]
    for name, value in schema.items():
        if name not in typed and not (isinstance(value, dict) and value):
            out.append(f"| `{name}` | {_cell(_default_text(run_default[name]))} | {_cell(comments.get(name, ''))} |")
    for name, value in schema.items():
        if not (isinstance(value, dict) and value):
            continue
        cls, owner = typed.get(name, (None, "every run"))
        fields = {f.name: f for f in dataclasses.fields(cls)} if cls else {}
        docs = _field_docs(cls) if cls else {}
        where = f"`{cls.__module__}.{cls.__qualname__}`" if cls else "the harness"
        out += ["", f"## `{name}`", "", f"Used by: {owner}. Checked by {where}.", "",
                "| key | type | default | range | meaning |", "|---|---|---|---|---|"]
        for key in value:
            f = fields.get(key)
            typ = str(f.type) if f else type(value[key]).__name__
            rng = _range_text(dict(f.metadata)) if f else ""
            meaning = docs.get(key) or comments.get(f"{name}.{key}", "")
            default = run_default[name][key]
            if default != value[key]:
                meaning = f"{meaning} (the dataclass default is {value[key]!r}; `configs/default.yaml` sets {default!r})".strip()
            out.append(f"| `{name}.{key}` | {_cell(typ)} | {_cell(_default_text(default))} | {_cell(rng)} | {_cell(meaning)} |")
    return "\n".join(out) + "\n"


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
        about = get_track(track).shipped_scenes().get(env.scene, "")
        loop = "closed" if env.loop else "open"
        out.append(f"| `{env_id}` | {track} | `{env.scene}`: {_cell(about)} | {loop} |")
    return "\n".join(out)


GENERATORS = {"associators": associators_markdown, "settings": settings_markdown, "cli": cli_markdown,
              "gym_envs": gym_envs_markdown}


def on_page_markdown(markdown: str, page, config, files) -> str:
    """Replace each ``<!-- generated: NAME -->`` line with the generated Markdown."""
    return MARKER.sub(lambda m: GENERATORS[m.group(1)](), markdown)


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
