"""The report's HTML: an overview ranking the methods and a page per suite with its sortable,
filterable table, column legend and pictures. Pages carry their CSS and script inline and name
pictures by relative paths (opens from ``file://``), and depend only on the inputs (same inputs,
same bytes)."""

from __future__ import annotations

import math
from html import escape
from importlib import resources

import pandas as pd

from ...scoring.loop_summary import BAND_LEGEND, band_mark
from ...viz.cd_diagram import cd_figure
from ...viz.plots import figure_bytes
from ..leaderboard import oracle_label
from .columns import BY_KEY, COUNT_COLUMNS, NOT_METRICS, Column, column
from .ranking import REFERENCE_METHODS, RULE, Ranking, rankings
from .suites import Suite, caption

FILTERS = (("scene", "scene"), ("difficulty", "difficulty"), ("backend", "back end"), ("method", "method"))
BETTER = {"high": "higher is better", "low": "lower is better", "": ""}


def _static(name: str) -> str:
    return resources.files(__package__).joinpath("static", name).read_text()


def document(title: str, here: str, suites: list[Suite], body: str) -> str:
    """A whole page: the navigation bar (overview, then each suite), ``body``, the sources."""
    links = [("index", "Overview")] + [(s.slug, s.title) for s in suites]
    nav = "".join(f'<a href="{slug}.html"{" class=here" if slug == here else ""}>{escape(name)}</a>'
                  for slug, name in links)
    sources = "".join(f"<li><code>{escape(s.source)}</code> (sha256 {s.digest[:12]})</li>" for s in suites)
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f'<meta name="generator" content="assocbench report">\n<title>{escape(title)}</title>\n'
            f'<style>\n{_static("report.css")}</style>\n<script>\n{_static("report.js")}</script>\n</head>\n'
            f'<body>\n<header><span class="brand">assocbench leaderboard</span>{nav}</header>\n<main>\n{body}</main>\n'
            f'<footer>Built by <code>assocbench report</code> from the leaderboards:<ul>{sources}</ul></footer>\n'
            f'</body>\n</html>\n')


def _num(value: float, digits: int, none: str = "n/a") -> str:
    return none if value is None or math.isnan(value) else f"{value:.{digits}f}"


def _cell_num(value: float, c: Column) -> str:
    """``_num`` with the column's digits; a count column's whole value (one seed's 3 frames, or
    a mean over seeds that is whole) without decimals: "3", not "3.0"."""
    whole = c.count and value is not None and math.isfinite(value) and float(value).is_integer()
    return _num(value, 0 if whole else c.digits)


def _v(value: float) -> str:
    """The exact value a cell sorts by ("" for none)."""
    return "" if value is None or math.isnan(value) else format(float(value), ".10g")


# --- overview -------------------------------------------------------------------------------
def overview_body(suites: list[Suite]) -> tuple[str, dict[str, bytes]]:
    """The ranking rule, a ranking table per kind of method with what it compared and its
    critical-difference diagrams, and the suites; returns the HTML and the diagrams."""
    out = ["<h1>Leaderboard across tracks</h1>",
           '<p class="lead">Every method of every leaderboard in this report, ranked by its track\'s primary metric '
           "in each scenario (a scene at a difficulty, with its back end) and seed, and placed by a significance test: "
           "methods that share a place could not be told apart. Each track's page has the full table (every metric, "
           "mean &plusmn; std over seeds), its plots and top views.</p>",
           f'<div class="rule"><b>Rank rule.</b> {escape(RULE)}</div>']
    pictures: dict[str, bytes] = {}
    for family in dict.fromkeys(s.family for s in suites):
        members = [s for s in suites if s.family == family]
        what = ", ".join(dict.fromkeys(s.track for s in members))
        heading = "Feature associators" if family == "feature" else f"The {family} track's methods"
        if members:
            ranked = rankings(members, heading)
            diagrams = {f"img/ranks/{r.slug}.png": _diagram(r) for r in ranked}
            pictures |= diagrams
            out += [f"<h2>{heading} ({what})</h2>", _ranking_table(ranked), _compared(ranked),
                    '<div class="gallery cd">' + "".join(
                        f'<figure><a href="{path}"><img src="{path}" alt="critical-difference diagram, {escape(r.title)}">'
                        f"</a><figcaption>critical-difference diagram, {escape(r.title)}</figcaption></figure>"
                        for path, r in zip(diagrams, ranked)) + "</div>"]
    out += ["<h2>Leaderboards in this report</h2>", _suite_list(suites)]
    return "\n".join(out) + "\n", pictures


def _ranking_table(ranked: list[Ranking]) -> str:
    """A row per method, a column per ranking: its place (methods not told apart share one) and mean rank."""
    overall = ranked[-1]
    order = list(overall.table["method"]) + sorted({m for r in ranked for m in r.table["method"]}
                                                   - set(overall.table["method"]))
    order += sorted({m for r in ranked for m in r.left_out} - set(order))
    head = ['<th class="text sortable" data-type="text">method<span class="unit"></span></th>']
    head += [f'<th class="sortable" data-type="num" title="{escape(_what(r))}">{escape(r.title)}'
             f'<span class="unit">place (mean rank)</span></th>' for r in ranked]
    head.append('<th class="sortable" data-type="num" title="blocks where its run diverged, was not ok or had no '
                'value (ranked last there)">ranked last<span class="unit">blocks, diverged or not ok</span></th>')
    rows = []
    for method in order:
        cells = [f'<td class="text" data-v="{escape(method)}">{escape(method)}</td>']
        last = 0
        for r in ranked:
            row = r.table[r.table["method"] == method]
            if len(row):
                place, mean = int(row["place"].iloc[0]), float(row["mean_rank"].iloc[0])
                last += int(row["last"].iloc[0]) if r is not overall or len(ranked) == 1 else 0
                cells.append(f'<td data-v="{_v(mean)}"><b>{place}</b> <span class="std">({mean:.2f})</span></td>')
            elif method in r.left_out:
                cells.append(f'<td class="out" data-v="" title="{escape(r.left_out[method])}">left out</td>')
            else:
                cells.append('<td data-v="">&ndash;</td>')
        cells.append(f'<td{" class=counted" if last else ""} data-v="{last}">{last}</td>')
        rows.append("<tr>" + "".join(cells) + "</tr>")
    return (f'<div class="scroll"><table class="ranking"><thead><tr>{"".join(head)}</tr></thead>\n<tbody>\n'
            + "\n".join(rows) + "\n</tbody></table></div>")


def _what(r: Ranking) -> str:
    """What a ranking compared, and its test's result, in one sentence."""
    t = r.test
    k = len(t.methods)
    blocks = (f"{r.scenarios} scenarios \u00d7 their seeds" if r.per_seed else
              f"its {r.scenarios} scenarios, means over seeds: no runs.csv, so the seeds cannot be blocks")
    words = f"{k} method{'s' * (k != 1)} over {t.blocks} blocks ({blocks})"
    if math.isnan(t.p):
        return words + "; nothing to test (fewer than 2 methods or blocks): placed by mean rank alone"
    verdict = (f"Nemenyi CD = {t.cd:.2f}" if t.rejects else "not rejected: every method shares 1st place")
    return (f"{words}; Friedman (Iman-Davenport) F({k - 1}, {(k - 1) * (t.blocks - 1)}) = {t.f:.2f}, "
            f"p = {t.p:.2g}; {verdict}")


def _compared(ranked: list[Ranking]) -> str:
    """Per ranking: what it compared, its test, and what it left out and why."""
    items = []
    for r in ranked:
        out = [f"<b>{escape(r.title)}</b>: {escape(_what(r))}."]
        if r.left_out:
            out.append("Left out: " + "; ".join(f"{escape(m)} ({escape(why)})" for m, why in r.left_out.items()) + ".")
        if r.scenarios_out:
            out.append("Scenarios left out: " + "; ".join(f"{escape(sc)}, {escape(why)}"
                                                           for sc, why in r.scenarios_out.items()) + ".")
        items.append("<li>" + " ".join(out) + "</li>")
    return '<ul class="compared">' + "".join(items) + "</ul>"


def _diagram(r: Ranking) -> bytes:
    """The ranking's critical-difference diagram as PNG bytes."""
    t = r.test
    names = list(t.methods)
    note = ("no test: fewer than 2 methods or blocks" if math.isnan(t.p) else
            f"Friedman p = {t.p:.2g}, {t.blocks} blocks" + ("" if t.rejects else f": no difference at \u03b1 = {t.alpha}"))
    return figure_bytes(cd_figure(names, t.mean_rank, t.cd if t.rejects else math.nan, t.cliques(), r.title, note))


def _suite_list(suites: list[Suite]) -> str:
    rows = ["<tr><th class=text>page</th><th class=text>track</th><th class=text>ranked by</th><th>scenarios</th>"
            "<th>methods</th><th>seeds</th><th class=text>source</th></tr>"]
    for s in suites:
        t = s.table
        seeds = "" if "seeds" not in t else f"{int(t['seeds'].min())}" + (
            f"&ndash;{int(t['seeds'].max())}" if t["seeds"].max() != t["seeds"].min() else "")
        rows.append(f'<tr><td class="text"><a href="{s.slug}.html">{escape(s.title)}</a></td>'
                    f'<td class="text">{escape(", ".join(filter(None, [s.track, s.loop_words])))}</td>'
                    f'<td class="text">{escape(s.primary.header)}, {BETTER[s.primary.better]}</td>'
                    f'<td>{t["scenario"].nunique()}</td><td>{t["method"].nunique()}</td><td>{seeds}</td>'
                    f'<td class="text"><code>{escape(s.source)}</code></td></tr>')
    return '<table class="suites">' + "\n".join(rows) + "</table>"


# --- one suite --------------------------------------------------------------------------------
def metric_columns(suite: Suite) -> list[Column]:
    """The metric columns to show: the primary metric, the catalogue's others in its order, then
    unknown numeric ones; a column with no value in any row is left out."""
    table = suite.table
    first = [suite.primary] + [c for c in BY_KEY.values() if c != suite.primary]
    known = [c for c in first if c.key in table and table[c.key].notna().any()]
    other = [column(k) for k in table if k not in BY_KEY and k not in NOT_METRICS and k != "backend"
             and not k.endswith("_std") and table[k].notna().any()]
    return known + other


def suite_body(suite: Suite, pictures: list[str]) -> str:
    """The suite's heading, filters, table, column legend and pictures (``pictures``: relative paths)."""
    t = suite.table
    columns = metric_columns(suite)
    seeds = f"over {int(t['seeds'].max())} seeds" if "seeds" in t else ""
    out = [f"<h1>{escape(suite.title)}</h1>",
           f'<p class="lead">{escape(suite.track)} track{", " + suite.loop_words if suite.loop_words else ""}. One row per scenario and '
           f"method: the mean &plusmn; std {seeds}. Click a column's header to sort by it; pick a scene, difficulty, "
           f"back end or method to filter. Ranked on the overview by {escape(suite.primary.header)} "
           f"({BETTER[suite.primary.better]}). Rows in <i>italics</i>: {_oracle_words(suite)}; rows in red are "
           f"<b>not ok</b> (numbers the harness could not trust; the status says why).</p>",
           _filters(t), _table(suite, columns), "<h2>Columns</h2>", _legend(suite, columns)]
    if pictures:
        figures = "".join(f'<figure><a href="{p}"><img src="{p}" alt="{escape(caption(name, suite))}"></a>'
                          f"<figcaption>{escape(caption(name, suite))}</figcaption></figure>"
                          for p, (name, _) in zip(pictures, suite.pictures))
        out += ["<h2>Plots and top views</h2>", f'<div class="gallery">{figures}</div>']
    return "\n".join(out) + "\n"


def _filters(t: pd.DataFrame) -> str:
    out = []
    for key, label in FILTERS:
        values = list(dict.fromkeys(t[key]))
        if len(values) > 1:
            options = "".join(f'<option value="{escape(v)}">{escape(v)}</option>' for v in values)
            out.append(f'<label>{label}<select data-filter="{key}"><option value="">all</option>{options}</select></label>')
    out.append('<label><span>&nbsp;</span><span><input type="checkbox" id="more"> more columns</span></label>'
               '<span class="count"></span>')
    return f'<div class="controls">{"".join(out)}</div>'


def _table(suite: Suite, columns: list[Column]) -> str:
    t = suite.table
    backend = t["backend"].ne("").any()
    labels = [("scene", "scene"), ("difficulty", "difficulty")] + ([("backend", "back end")] if backend else [])
    head = [f'<th class="text sortable" data-type="text">{label}<span class="unit"></span></th>'
            for _, label in labels + [("method", "method")]]
    for c in columns:
        head.append(f'<th class="sortable{"" if c.shown(suite.kind) else " more"}" data-type="num" title="{escape(c.meaning)}">'
                    f'{escape(c.label)}<span class="unit">{escape(c.unit) if c.unit else "&nbsp;"}</span></th>')
    if "anees_lo" in t:
        head.append('<th title="two-sided 95 % chi-square band of one run\'s ANEES">ANEES band'
                    '<span class="unit">95 %, NEES</span></th>')
    counts = [k for k in COUNT_COLUMNS if k in t]
    # the counts behind "more columns": a count above 0 is a badge beside the method's name
    head += [f'<th class="sortable more" data-type="num" title="{escape(COUNT_COLUMNS[k][1])}">{COUNT_COLUMNS[k][0]}'
             f'<span class="unit">{"seeds" if k == "diverged" else "frames"}</span></th>' for k in counts]
    head.append('<th class="text sortable" data-type="text">status<span class="unit"></span></th>')
    rows = [_row(r, labels, columns, counts, suite.kind, oracle_label(suite.scored_against)) for _, r in t.iterrows()]
    stacked = " stacked" if suite.kind == "loop" or suite.family != "feature" else ""   # many columns: each std under its mean, to fit 1400 px
    return (f'<div class="scroll"><table class="filterable{stacked}"><thead><tr>{"".join(head)}</tr></thead>\n'
            '<tbody>\n' + "\n".join(rows) + "\n</tbody></table></div>")


def _oracle_words(suite: Suite) -> str:
    word = suite.scored_against
    if word == "truth":
        return "the true association, a reference, not a method"
    return (f"the dataset's own {escape(word)} association, not a method; every score on this page is against that "
            f"{escape(word)} (its labels, its landmarks, the path a solver fitted to them), not ground truth")


def _row(r: pd.Series, labels, columns: list[Column], counts: list[str], kind: str, oracle_name: str) -> str:
    oracle = r["method"] in REFERENCE_METHODS
    name = oracle_name if oracle else r["method"]
    attrs = "".join(f' data-{k}="{escape(str(r[k]))}"' for k in ("scene", "difficulty", "backend", "method"))
    look = ' class="oracle"' if oracle else ' class="notok"' if r["status"] != "ok" else ""
    cells = [f'<td class="text" data-v="{escape(str(r[k]))}">{escape(str(r[k]))}</td>' for k, _ in labels]
    # the badges beside the name, not the status: the status is the last column, off-screen on the wide loop pages
    cells.append(f'<td class="text name" data-v="{escape(name)}">{escape(name)}{_badges(r, counts)}</td>')
    for c in columns:
        std = r.get(c.key + "_std")
        spread = f' <span class="std">&plusmn; {_cell_num(std, c)}</span>' if std is not None and pd.notna(
            std) and pd.notna(r[c.key]) else ""
        cells.append(f'<td{"" if c.shown(kind) else " class=more"} data-v="{_v(r[c.key])}">{_cell_num(r[c.key], c)}'
                     f"{spread}</td>")
    if "anees_lo" in r:
        mark = band_mark(r.get("anees", float("nan")), r["anees_lo"], r["anees_hi"])
        cells.append(f'<td data-v="{_v(r["anees_lo"])}">[{_num(r["anees_lo"], 2)}, {_num(r["anees_hi"], 2)}]'
                     f'{" " + mark if mark else ""}</td>')
    for k in counts:
        of = r["seeds"] if k == "diverged" else r.get("frames", float("nan"))
        hit = ' class="more counted"' if pd.notna(r[k]) and r[k] > 0 else ' class="more"'
        cells.append(f'<td{hit} data-v="{_v(r[k])}">{_num(r[k], 0)} / {_num(of, 0)}</td>')
    cells.append(f'<td class="text" data-v="{escape(str(r["status"]))}">{escape(str(r["status"]))}</td>')
    return f"<tr{look}{attrs}>" + "".join(cells) + "</tr>"


def _badges(r: pd.Series, counts: list[str]) -> str:
    """A badge by the method's name per counted failure (budget spent, failed frames, diverged
    seeds): the row stays ok, but the failure must not be missed."""
    return "".join(f' <span class="badge" title="{escape(COUNT_COLUMNS[k][1])}">{_num(r[k], 0)} {COUNT_COLUMNS[k][0]}'
                   f"</span>" for k in counts if pd.notna(r[k]) and r[k] > 0)


# the catalogue's words for a simulation's truth, and what they become for a recording's reference
REFERENCE_WORDS = (("are true", "agree with the reference"), ("true pairings", "reference pairings"),
                   ("the true one", "the reference's"), ("than the truth", "than the reference"),
                   ("as the truth", "as the reference"), ("true outcome", "reference outcome"))


def against_reference(text: str) -> str:
    """A column's meaning for a suite scored against a recording's reference, not a truth."""
    for truth, reference in REFERENCE_WORDS:
        text = text.replace(truth, reference)
    return text


def _legend(suite: Suite, columns: list[Column]) -> str:
    items = [("scene / difficulty / back end", "the scenario, split from its name scene/difficulty-backend (the back "
              "end: the estimator, the line extractor or the ICP target)") if suite.table["backend"].ne("").any()
             else ("scene / difficulty", "the scenario, split from its name scene/difficulty")]
    items += [(c.header, escape(against_reference(c.meaning) if suite.scored_against == "reference" else c.meaning)
               + (f"; {BETTER[c.better]}" if c.better else "")
               + ("" if c.shown(suite.kind) else " (behind &ldquo;more columns&rdquo;)")) for c in columns]
    items += [(f"{label} [{'seeds' if k == 'diverged' else 'frames'}]", f"{meaning} (behind &ldquo;more columns&rdquo;; "
               "a count above 0 is a badge beside the method's name)")
              for k, (label, meaning) in COUNT_COLUMNS.items() if k in suite.table]
    if "anees_lo" in suite.table:
        items.append(("ANEES band [95 %, NEES]", "two-sided 95 % chi-square band of one run's ANEES; "
                      + escape(BAND_LEGEND)))
    items.append(("status", "ok, or why the harness could not trust the row's numbers"))
    return '<dl class="legend">' + "".join(f"<dt>{escape(h)}</dt><dd>{m}</dd>" for h, m in items) + "</dl>"
