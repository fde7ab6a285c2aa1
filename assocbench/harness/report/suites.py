"""Read one leaderboard folder into what the report shows: its table, track and loop, primary metric
and pictures. Those come from the folder's card (``leaderboard.json``,
``harness.leaderboard.card``), so a plugin's leaderboard reads right with the plugin installed or
not; a folder without a card asks the track registry. An unusable folder is a one-line ``UserError``
naming the file and what to do."""

from __future__ import annotations

import csv
import hashlib
import io
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import UserError
from ...scoring.aggregate import OK
from ...tracks.inference import infer_track
from ..leaderboard import CARD_KEYS, scenario_key
from .columns import BY_KEY, COUNT_COLUMNS, WHOLE, Column, value_range

CSV_NAME = "leaderboard.csv"
CARD_NAME = "leaderboard.json"
RUNS_NAME = "runs.csv"   # every run's summary (scenario x method x seed), beside a feature track's means
LABEL_COLUMNS = ("scenario", "method", "status", "error", "scene", "difficulty")
# the pictures `leaderboard` writes, in the order a reader wants them; others follow by name
PICTURE_ORDER = ("leaderboard_pr.png", "leaderboard_ate.png", "leaderboard_nees.png", "leaderboard_runtime.png",
                 "leaderboard_map.png")
CAPTIONS = {"pr": "precision against recall, a panel per scene and difficulty",
            "ate": "ATE per method and scenario", "nees": "pose NEES over time against its chi-square band",
            "runtime": "runtime of associate() against the number of candidates", "map": "top view"}


@dataclass
class Suite:
    """One leaderboard: ``table`` a row per scenario x method with ``scene``, ``difficulty``,
    ``backend`` split from the scenario; ``runs`` a row per run where the folder has them (None:
    means only)."""

    source: str
    digest: str
    table: pd.DataFrame
    card: dict                      # the folder's leaderboard.json (``harness.leaderboard.card``)
    pictures: list[tuple[str, bytes]] = field(default_factory=list)
    runs: pd.DataFrame | None = None
    title: str = ""
    slug: str = ""

    @property
    def track(self) -> str:
        return self.card["track"]

    @property
    def kind(self) -> str:
        """``loop`` for a closed-loop suite, else ``open`` (which columns a page shows first)."""
        return "loop" if self.card["loop"] else "open"

    @property
    def family(self) -> str:
        """What kind of method it ranks: ``feature`` (association problems), or its track's own."""
        return self.card["methods"]

    @property
    def primary(self) -> Column:
        """The column its methods are ranked by: the track's primary metric."""
        m = self.card["primary"]
        known = BY_KEY.get(m["name"])
        return known or Column(m["name"], m["name"].replace("_", " "), f"the {self.track} track's primary metric",
                               "high" if m["higher_better"] else "low", 3)

    @property
    def loop_words(self) -> str:
        return self.card["words"]

    @property
    def scored_against(self) -> str:
        """What its runs were scored against: ``truth``, or a recorded track's ``reference``."""
        return self.card.get("scored_against", "truth")


def read_suite(path: Path, source: str) -> Suite:
    """The leaderboard in ``path`` (a folder holding ``leaderboard.csv``, or that file)."""
    csv = path / CSV_NAME if path.is_dir() else path
    if not path.exists():
        raise UserError(f"{source} does not exist: give folders written by `assocbench leaderboard --out DIR` "
                        f"(e.g. results/loop)")
    if not csv.is_file():
        raise UserError(f"{source} holds no {CSV_NAME}: give folders written by `assocbench leaderboard --out DIR` "
                        f"(e.g. results/loop)")
    data = csv.read_bytes()
    table = _parse(data, source if csv == path else f"{source}/{CSV_NAME}")
    card = read_card(csv.parent / CARD_NAME, table, source)
    metric = card["primary"]["name"]
    if metric not in table:
        raise UserError(f"{source}/{CSV_NAME} has no column {metric}, the metric its track ranks by; regenerate it "
                        "with `assocbench leaderboard`")
    runs = None
    if "seed" in table:   # a track's own leaderboard may list every run; the report shows the mean over seeds
        runs, table = table, _per_scenario(table)
    elif (csv.parent / RUNS_NAME).is_file():
        runs = _runs(csv.parent / RUNS_NAME, f"{source}/{RUNS_NAME}", table, metric)
    table = _with_parts(table)
    pictures = [(p.name, p.read_bytes()) for p in _pictures(csv.parent)] if csv.parent.is_dir() else []
    return Suite(source, hashlib.sha256(data).hexdigest(), table, card, pictures, runs)


def _runs(path: Path, name: str, table: pd.DataFrame, metric: str) -> pd.DataFrame:
    """The per-seed rows beside a table of means, checked to hold the same scenarios and methods
    and the ``metric`` they are ranked by."""
    runs = _parse(path.read_bytes(), name)
    if "seed" not in runs or metric not in runs:
        raise UserError(f"{name} has no {'seed' if 'seed' not in runs else metric} column; regenerate it with "
                        "`assocbench leaderboard`")
    pairs = [set(zip(t["scenario"], t["method"])) for t in (runs, table)]
    if pairs[0] != pairs[1]:
        raise UserError(f"{name} does not hold the runs of the {CSV_NAME} beside it (other scenarios or methods); "
                        "regenerate both with `assocbench leaderboard`")
    return runs


def _parse(data: bytes, name: str) -> pd.DataFrame:
    """The CSV's table, checked: the label columns, a metric to rank by, numbers in every other column."""
    fix = "regenerate it with `assocbench leaderboard`"
    try:
        table = pd.read_csv(io.BytesIO(data), dtype={"scenario": str, "method": str, "status": str})
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
        raise UserError(f"{name} is not a readable CSV ({str(exc).splitlines()[0]}); {fix}") from None
    missing = [c for c in ("scenario", "method") if c not in table]
    if missing:
        raise UserError(f"{name} is not a leaderboard: no {' or '.join(missing)} column; {fix}")
    if not len(table) or table[["scenario", "method"]].isna().any().any():
        raise UserError(f"{name} has no rows or a row without scenario or method; {fix}")
    key = ["scenario", "method"] + (["seed"] if "seed" in table else [])
    twice = table[table.duplicated(key)]
    if len(twice):
        r = twice.iloc[0]
        raise UserError(f"{name} has two rows for method {r['method']} on {r['scenario']}; {fix}")
    text = [c for c in table if c not in LABEL_COLUMNS and not pd.api.types.is_numeric_dtype(table[c])]
    bad = [c for c in text if c in BY_KEY or c in COUNT_COLUMNS or c in ("seed", "seeds", "frames")]
    if bad:
        raise UserError(f"{name}: column {bad[0]} holds text where numbers belong; {fix}")
    table = table.drop(columns=text)   # labels a newer harness may add; the report ranks and sorts numbers
    _check_rows(data, table, name)
    _check_values(table, name)
    if "status" not in table:   # a leaderboard older than the status column: every row was measured
        table["status"] = OK
    return table


def _where(table: pd.DataFrame, i: int, name: str) -> str:
    """``name`` and row ``i`` by its line in the file and its scenario and method."""
    return f"{name} line {i + 2} ({table['scenario'].iloc[i]}, {table['method'].iloc[i]})"


def _check_rows(data: bytes, table: pd.DataFrame, name: str) -> None:
    """Refuse a row with fewer fields than the header (a cut file: pandas would fill NaN and read
    the status as ok) or an empty status, seeds or frames."""
    lines = [row for row in csv.reader(io.StringIO(data.decode("utf-8", "replace"))) if row]
    short = [i for i, row in enumerate(lines[1:]) if len(row) != len(lines[0])]
    if short:
        i = short[0]
        raise UserError(f"{_where(table, i, name)} has {len(lines[i + 1])} fields, the header {len(lines[0])}: the file "
                        f"is cut or damaged; regenerate it with `assocbench leaderboard`")
    for key in ("status", "seeds", "frames"):
        if key in table and table[key].isna().any():
            raise UserError(f"{_where(table, int(np.flatnonzero(table[key].isna())[0]), name)} has no {key}; "
                            f"regenerate it with `assocbench leaderboard`")


def _check_values(table: pd.DataFrame, name: str) -> None:
    """Refuse a number outside its column's range (``columns.value_range``), an infinite one or a
    fractional count, naming line and column (the report would rank ``f1=inf`` first)."""
    for key in [c for c in table if c not in LABEL_COLUMNS]:
        lo, hi = value_range(key)
        values = table[key].to_numpy(dtype=float)
        bad = ~np.isnan(values) & ~((values >= lo) & (values <= hi) & np.isfinite(values))
        if key in WHOLE:
            bad |= ~np.isnan(values) & (values != np.round(values))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            expect = f"a whole number in [{lo:g}, {hi:g}]" if key in WHOLE else f"a finite number in [{lo:g}, {hi:g}]"
            raise UserError(f"{_where(table, i, name)}, column {key}: {values[i]:.6g} is not {expect}; "
                            f"regenerate it with `assocbench leaderboard`")


def read_card(path: Path, table: pd.DataFrame, source: str) -> dict:
    """The folder's card, checked; without one, the card its track would write, the track found from
    the first row's scene and method."""
    if path.is_file():
        try:
            card = json.loads(path.read_text())
            missing = [k for k in CARD_KEYS if k not in card]
        except (OSError, ValueError) as exc:
            raise UserError(f"{source}/{CARD_NAME} is not readable JSON ({exc}); regenerate the folder with "
                            "`assocbench leaderboard`") from None
        if missing or not isinstance(card.get("primary"), dict) or "name" not in card["primary"]:
            raise UserError(f"{source}/{CARD_NAME} lacks {', '.join(missing) or 'primary.name'}; regenerate the "
                            "folder with `assocbench leaderboard`")
        return card
    from ..leaderboard import card as track_card

    scene = str(table["scenario"].iloc[0]).rpartition("/")[0]
    try:
        track = infer_track(scene, str(table["method"].iloc[0]))
    except (UserError, OSError, ValueError):
        raise UserError(f"{source} has no {CARD_NAME} and its scenes name no track here; regenerate it with "
                        "`assocbench leaderboard` (which writes the card)") from None
    return track_card(track, "ate_rmse" in table or "anees" in table)


def _per_scenario(runs: pd.DataFrame) -> pd.DataFrame:
    """Mean and std (ddof 0) over seeds per scenario x method of a CSV of every run; ok only when
    every seed was; counted columns and ``frames`` summed (the page shows "k / frames")."""
    metrics = [c for c in runs if c not in LABEL_COLUMNS and c != "seed"]
    grouped = runs.groupby(["scenario", "method"], sort=False)
    table = grouped[metrics].agg(lambda col: col.mean(skipna=False))
    table = table.join(grouped[[c for c in metrics if c in BY_KEY]].std(ddof=0).fillna(0.0).add_suffix("_std"))
    table["status"] = grouped["status"].agg(lambda s: OK if (s == OK).all() else next(v for v in s if v != OK))
    table["seeds"] = grouped.size()
    for summed in [c for c in (*COUNT_COLUMNS, "frames") if c in runs]:
        table[summed] = grouped[summed].sum()
    return table.reset_index()


def _with_parts(table: pd.DataFrame) -> pd.DataFrame:
    """Scene, difficulty and back end split from ``scene/difficulty-backend``, rows in leaderboard
    order, then CSV order."""
    split = table["scenario"].str.rpartition("/")
    parts = split[2].str.partition("-")
    table = table.assign(scene=split[0], difficulty=parts[0], backend=parts[2])
    rank = {s: k for k, s in enumerate(sorted(table["scenario"].unique(), key=scenario_key))}
    order = np.argsort(table["scenario"].map(rank).to_numpy(), kind="stable")
    return table.iloc[order].reset_index(drop=True)


def _pictures(folder: Path) -> list[Path]:
    """The folder's PNG pictures, the known ones first in reading order."""
    found = sorted(folder.glob("*.png"))
    known = [folder / name for name in PICTURE_ORDER if (folder / name).is_file()]
    return known + [p for p in found if p not in known]


def caption(name: str, suite: Suite) -> str:
    """Words for a leaderboard picture's file name (``leaderboard_map_park.png``: top view, park;
    ``leaderboard_map.png`` is the first scene's, or a track's own top view)."""
    stem = name.removesuffix(".png").removeprefix("leaderboard_")
    kind, _, scene = stem.partition("_")
    if stem == "map":
        return f"top view, {suite.table['scene'].iloc[0]}" if suite.kind == "loop" else "top view"
    if kind in CAPTIONS:
        return CAPTIONS[kind] + (f", {scene}" if scene else "")
    return stem.replace("_", " ")
