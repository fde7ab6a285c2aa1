"""Leaderboard files: CSV, Markdown and two PNG plots (drawn by ``viz.plots``), written atomically."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..atomic import atomic_path, write_text
from ..scoring.aggregate import SUMMARY_COLUMNS, leaderboard_table
from ..scoring.loop_summary import BAND_LEGEND, CHAOTIC_LEGEND, CHAOTIC_MARK, LOOP_COLUMNS, band_mark, chaotic
from ..tracks.base import Track
from ..tracks.capabilities import OwnFrames, TopView, has
from ..viz.plots import pr_figure, runtime_figure, save_figure
from .loop_truth import REVISIT_GAP

MD_COLUMNS = [("method", "method"), ("precision", "precision"), ("recall", "recall"), ("f1", "F1"),
              ("perfect", "perfect frames"), ("surprisal_gap", "surprisal gap"),
              ("runtime_median_ms", "runtime ms (median)"), ("proven_optimal", "proven optimal"),
              ("true_mass", "true mass")]
LOOP_MD_COLUMNS = [("method", "method"), ("ate_rmse", "ATE m"), ("rot_rmse_deg", "rot RMSE deg"),
                   ("anees", "ANEES"), ("precision", "precision"), ("recall", "recall"),
                   ("duplicates", "duplicates"), ("false_landmarks", "false landmarks"), ("map_rmse", "map RMSE m"),
                   ("runtime_median_ms", "runtime ms (median)")]
DIFFICULTY_ORDER = ("easy", "medium", "hard")
CARD_KEYS = ("track", "summary", "loop", "words", "methods", "primary", "units")
ORACLE_LABEL = "oracle (truth)"   # a simulated track's; a recorded track's is "oracle (reference)" (oracle_label)


def oracle_label(scored_against: str = "truth") -> str:
    """The oracle's row name: ``oracle (truth)``, or ``oracle (reference)`` on a recorded track."""
    return f"oracle ({scored_against})"


def oracle_words(scored_against: str) -> str:
    """The legend's sentence on the oracle row, for a track scored against truth or a reference."""
    if scored_against == "truth":
        return f"**{ORACLE_LABEL}** is the true association, available only to the harness: the best the estimator\n" \
               "can do, not a method."
    return (f"**{oracle_label(scored_against)}** is the dataset's {scored_against} association (its own labels, not "
            "ground truth), available only to the harness: not a method. Every score here is against that "
            f"{scored_against}: its labels, its landmarks and the path a solver fitted to them.")


def extra_columns(track: Track, loop: bool) -> list[str]:
    """The summary columns of the track's own (``RunScores``) beyond the shared ones."""
    return [c for c in track.columns(loop).summary if c not in SUMMARY_COLUMNS + LOOP_COLUMNS]


def card(track: Track, loop: bool) -> dict:
    """What ``leaderboard.json`` says of a suite, all from its track: the track, open or closed loop
    (in words), the kind of method it ranks, the primary metric with direction and unit, the track's
    own columns' units, and what it is scored against (``truth`` or a ``reference``). The report
    reads it without the registry."""
    cols = track.columns(loop)
    own = has(track, OwnFrames)
    words = "closed loop" if loop else ("" if own else "open loop")   # a frame loop of its own: its name says it
    return {"track": track.name, "summary": track.summary, "loop": bool(loop), "words": words,
            "methods": track.name if own else "feature",
            "primary": {"name": cols.primary.name, "higher_better": cols.primary.higher_better,
                        "unit": cols.primary.unit}, "units": dict(cols.units), "scored_against": cols.scored_against}


def write_card(out: Path, track: Track, loop: bool) -> Path:
    """Write ``leaderboard.json`` (``card``) into ``out``, atomically."""
    path = out / "leaderboard.json"
    write_text(path, json.dumps(card(track, loop), indent=1, sort_keys=True) + "\n")
    return path


def scenario_key(scenario: str, difficulties: Sequence[str] = ()) -> tuple:
    """Sort key of ``scene/difficulty``: scene, then easy, medium, hard, then the suite's
    ``difficulties`` order, then name."""
    scene, _, difficulty = scenario.rpartition("/")
    known = list(DIFFICULTY_ORDER) + [d for d in difficulties if d not in DIFFICULTY_ORDER]
    return scene, known.index(difficulty) if difficulty in known else len(known), difficulty


def order_scenarios(table: pd.DataFrame, difficulties: Sequence[str] = ()) -> pd.DataFrame:
    """``table`` with its scenarios in :func:`scenario_key` order, rows within one kept in order."""
    rank = {s: k for k, s in enumerate(sorted(table["scenario"].unique(), key=lambda s: scenario_key(s, difficulties)))}
    order = table["scenario"].map(rank).to_numpy()
    return table.iloc[np.argsort(order, kind="stable")].reset_index(drop=True)


def loop_markdown(table: pd.DataFrame, difficulties: Sequence[str] = (), estimator: str = "the track's",
                  scored_against: str = "truth", extra: Sequence[str] = ()) -> str:
    """The closed-loop leaderboard: a Markdown table per scenario, ``mean ± std`` over seeds, by
    ATE, ``oracle`` marked as the reference; ``estimator`` says what the pairings update,
    ``scored_against`` and ``extra`` as in ``to_markdown``."""
    against = "" if scored_against == "truth" else f" against the {scored_against} path"
    lines = ["# Closed-loop leaderboard", "",
             "Mean ± std over seeds, sorted by ATE within each scenario. Generated by `assocbench leaderboard "
             f"--suite <suite>`. Each method's own pairings update the track's estimator ({estimator}); the next "
             "frame's problem comes from it.",
             f"*ATE*: RMSE of the position error{against} of each frame's pose as the estimator had it then (no "
             "alignment, as",
             f"`evo_ape tum {scored_against}.txt estimate.txt`); *ATE smoothed*: of a smoother's final estimate of every "
             "pose;",
             "*ANEES*: mean pose NEES (its degrees of freedom are the pose's: 6 in space, 3 in the plane), with the two-sided 95 % χ² band for one run in",
             "brackets (it assumes independent frames, which one run's are not); " + BAND_LEGEND + ";",
             "*diverged*: seeds whose NEES stayed above χ²(0.999) for 5 frames; *precision / recall*: of the pairings",
             "in the loop; *duplicates / false landmarks / map RMSE*: the final map's (slam mode; 0 on a known map); *loop closures*:",
             f"revisits (a landmark measured again after {REVISIT_GAP} frames unseen) paired with its old map entry / "
             "revisits.",
             oracle_words(scored_against), CHAOTIC_LEGEND + ".", ""]
    closures = "revisits" in table and table["revisits"].fillna(0).gt(0).any()
    smoothed = "ate_smoothed" in table and not np.allclose(table["ate_smoothed"], table["ate_rmse"], equal_nan=True)

    def cells(r: pd.Series) -> list[str]:
        out = [_cell(r, col) for col, _ in LOOP_MD_COLUMNS[1:]]
        mark = band_mark(r["anees"], r["anees_lo"], r["anees_hi"])
        out[2] += f" [{r['anees_lo']:.2f}, {r['anees_hi']:.2f}]{' ' + mark if mark else ''}" if pd.notna(r["anees"]) else ""
        out += [f"{r['loop_closures']:.1f} / {r['revisits']:.1f}"] if closures else []
        out += [_cell(r, "ate_smoothed")] if smoothed else []
        out += [_cell(r, col) for col in extra]
        return out + [f"{int(r['diverged'])}/{int(r['seeds'])}", f"{int(r['failures'])}/{int(r['frames'])}"]

    headers = ([h for _, h in LOOP_MD_COLUMNS] + (["loop closures"] if closures else [])
               + (["ATE smoothed m"] if smoothed else []) + [c.replace("_", " ") for c in extra] + ["diverged", "failed"])
    flag = lambda r: f" {CHAOTIC_MARK}" if chaotic(r["diverged"]) else ""  # noqa: E731
    return "\n".join(lines + scenario_tables(table, difficulties, headers, cells, oracle_label(scored_against), flag))


def scenario_tables(table: pd.DataFrame, difficulties: Sequence[str], headers: list[str], cells,
                    oracle: str = ORACLE_LABEL, flag=lambda r: "") -> list[str]:
    """Markdown lines of a table per scenario, rows in ``table``'s order (the name, ``flag(row)``,
    **not ok**, ``cells(row)``), each not-ok reason after its table."""
    lines = []
    table = order_scenarios(table, difficulties)
    for scenario in table["scenario"].unique():
        lines += [f"## {scenario}", "", "| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
        notes = []
        for _, r in table[table["scenario"] == scenario].iterrows():
            name = (f"**{oracle}**" if r["method"] == "oracle" else str(r["method"])) + flag(r)
            if r.get("status", "ok") != "ok":
                name += " **not ok**"
                notes.append(f"- {r['method']}: {r['status']}")
            lines.append("| " + " | ".join([name] + cells(r)) + " |")
        lines += [""] + (notes + [""] if notes else [])
    return lines


def _cell(r: pd.Series, col: str) -> str:
    """``mean ± std`` with the column's digits, or n/a."""
    digits = 2 if col in ("surprisal_gap", "runtime_median_ms", "anees", "duplicates", "false_landmarks") else 3
    digits = 4 if col in ("ate_rmse", "ate_smoothed", "map_rmse") else digits
    return "n/a" if pd.isna(r[col]) else f"{r[col]:.{digits}f} ± {r[col + '_std']:.{digits}f}"


def to_markdown(table: pd.DataFrame, difficulties: Sequence[str] = (), scored_against: str = "truth",
                extra: Sequence[str] = ()) -> str:
    """A Markdown table per scenario, ``mean ± std`` over seeds, in leaderboard order;
    ``scored_against``: ``truth`` or ``reference``; ``extra``: the track's columns."""
    against = "" if scored_against == "truth" else (
        f" Every score is against the dataset's {scored_against} association (its own labels, not ground truth).")
    lines = ["# Leaderboard", "",
             f"Mean ± std over seeds. Sorted by F1 within each scenario. Generated by `assocbench leaderboard`.{against}",
             "*timed out*: frames where the method spent its search budget and returned its best hypothesis so far;",
             "*failed*: frames where it raised, returned an invalid association, overran its time limit or its worker",
             "died;",
             "*proven optimal*: share of frames whose answer the method proved optimal (JCBB: the largest jointly",
             "compatible hypothesis; CCDA: a maximum clique; each search ended within its budget); n/a for methods that",
             "make no such claim;",
             "*true mass*: for soft associators (JPDA), the mean probability put on each candidate's "
             f"{'true' if scored_against == 'truth' else scored_against} outcome.",
             "A method marked **not ok** has numbers that cannot be trusted (failed frames, no candidates or nothing",
             "associated in some seed's run); the reason follows the table.", ""]
    def cells(r: pd.Series) -> list[str]:
        return [_cell(r, col) for col, _ in MD_COLUMNS[1:]] + [_cell(r, col) for col in extra] + [
            f"{int(r['timed_out'])}/{int(r['frames'])}", f"{int(r['failures'])}/{int(r['frames'])}"]

    headers = [h for _, h in MD_COLUMNS] + [c.replace("_", " ") for c in extra] + ["timed out", "failed"]
    return "\n".join(lines + scenario_tables(table, difficulties, headers, cells))


def _grid(table: pd.DataFrame, difficulties: Sequence[str]) -> tuple[list[str], list[str]]:
    """Scenes (rows) and difficulties (columns) of the plot grid, each in leaderboard order."""
    keys = [scenario_key(s, difficulties) for s in table["scenario"].unique()]
    scenes = list(dict.fromkeys(k[0] for k in sorted(keys)))
    columns = list(dict.fromkeys(k[2] for k in sorted(keys, key=lambda k: k[1:])))
    return scenes, columns


def plot_precision_recall(table: pd.DataFrame, path: Path, difficulties: Sequence[str] = ()) -> None:
    """Precision against recall: a row per scene, a column per difficulty, each method its own mark
    (``viz.plots``)."""
    table = order_scenarios(table, difficulties)
    save_figure(pr_figure(table, *_grid(table, difficulties)), path)


def plot_runtime(frames: pd.DataFrame, path: Path) -> None:
    """Runtime against the number of candidates: frames as dots, per-method binned medians."""
    save_figure(runtime_figure(frames), path)


def write_leaderboard(summaries: pd.DataFrame, frames: pd.DataFrame, out: Path, track: Track,
                      scenes: Mapping[str, str] | None = None) -> dict[str, Path]:
    """Write ``leaderboard.csv`` (means over seeds), ``runs.csv`` (every run: the report's
    significance test), ``leaderboard.md`` and two plots into ``out`` (a closed loop adds
    ``write_loop_plots``); returns the paths. ``scenes``: scene name -> its source."""
    difficulties = list(dict.fromkeys(summaries["difficulty"])) if "difficulty" in summaries else []
    loop = "ate_rmse" in summaries
    extra, scored_against = extra_columns(track, loop), track.columns(loop).scored_against
    table = order_scenarios(leaderboard_table(summaries, extra), difficulties)
    paths = {k: out / f"leaderboard{s}" for k, s in
             (("csv", ".csv"), ("md", ".md"), ("pr", "_pr.png"), ("runtime", "_runtime.png"))}
    paths["runs"] = out / "runs.csv"
    for path, rows in ((paths["csv"], table), (paths["runs"], run_rows(summaries, difficulties))):
        with atomic_path(path) as tmp:
            rows.to_csv(tmp, index=False, float_format="%.6g")
    words = getattr(track, "estimator_words", "the track's")
    write_text(paths["md"], loop_markdown(table, difficulties, words, scored_against, extra) if loop
               else to_markdown(table, difficulties, scored_against, extra))
    plot_precision_recall(table, paths["pr"], difficulties)
    plot_runtime(frames, paths["runtime"])
    if loop:
        paths |= write_loop_plots(table, frames, out, difficulties, track, scenes or {})
    return paths


def run_rows(summaries: pd.DataFrame, difficulties: Sequence[str] = ()) -> pd.DataFrame:
    """Every run's summary, in leaderboard order, with ``diverged`` (1 where a closed-loop run's
    NEES left its bound) beside ``diverged_at``."""
    rows = summaries.sort_values("seed", kind="stable")   # within a seed, the suite's order of methods
    if "diverged_at" in rows:
        rows = rows.assign(diverged=(rows["diverged_at"] >= 0).astype(int))
    first = ["scenario", "method", "seed"]
    return order_scenarios(rows[first + [c for c in rows if c not in first]], difficulties)


def write_loop_plots(table: pd.DataFrame, frames: pd.DataFrame, out: Path, difficulties: Sequence[str],
                     track: Track, scene_paths: Mapping[str, str]) -> dict:
    """A closed loop's ``leaderboard_ate.png``, ``leaderboard_nees.png`` and, with a ``TopView``,
    ``leaderboard_map[_<scene>].png`` (each method at the last difficulty and lowest seed)."""
    from ..viz.loop_plots import ate_figure, nees_figure

    names, columns = _grid(table, difficulties)
    paths = {k: out / f"leaderboard_{k}.png" for k in ("ate", "nees")}
    scored_against = track.columns(True).scored_against
    save_figure(ate_figure(table, names, columns, scored_against), paths["ate"])
    save_figure(nees_figure(frames, names, columns, scored_against), paths["nees"])
    if not has(track, TopView):
        return paths
    for k, name in enumerate(names):   # a top view per scene, at its hardest difficulty, lowest seed
        key = f"map_{name}" if k else "map"
        paths[key] = out / f"leaderboard_{key}.png"
        save_figure(map_view(frames, name, columns[-1], track, scene_paths.get(name, name)), paths[key])
    return paths


def map_view(frames: pd.DataFrame, scene: str, difficulty: str, track: Track, path: str):
    """The track's top view of every method's run on ``scene/difficulty`` at the lowest seed;
    ``path``: the scene's source."""
    scenario = f"{scene}/{difficulty}"
    one = frames[frames["scenario"] == scenario]
    one = one[one["seed"] == one["seed"].min()]
    return track.map_figure(one, path, f"{scenario} seed {one['seed'].min()}")
