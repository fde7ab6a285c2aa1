"""Dense suites: scenes × difficulties × methods × seeds of the dense track, run, tabled and checked.

A dense suite is a suite file (``harness/suite.py``'s keys) whose methods are all dense
associators (``projective``, ``kdtree``). Runs go to worker processes (``--jobs``); each distinct
depth sequence is rendered once first, so workers never render the same frames twice. The
leaderboard is ``leaderboard.csv`` (every run), ``leaderboard.md`` (mean over seeds) and
``leaderboard_map.png`` (each scenario's fused maps, first seed, coloured by error).
"""

from __future__ import annotations

import math
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import UserError
from ..scoring.aggregate import OK
from ..tracks.dense.summary import DENSE_COLUMNS
from ..validation import check_number
from .check import write_ok_table
from .config import defaults, merge, read_yaml, run_spec
from ..tracks.dense.spec import DenseRunSpec, is_dense
from .suite import SUITE_KEYS, _crossed, _list, _methods, _refuse_duplicates

HIGHER_BETTER = ("precision", "recall")
LOWER_BETTER_MM = ("ate_mm", "map_median_mm")


@dataclass(frozen=True)
class DenseSuite:
    name: str
    runs: tuple    # ((scenario, method label, seed, DenseRunSpec), ...)
    tolerance: float
    ate_tolerance: float   # m

    def rows(self) -> list[tuple[str, str]]:
        return list(dict.fromkeys((sc, label) for sc, label, _, _ in self.runs))


def is_dense_suite(path: Path) -> bool:
    """Whether the suite file's methods are dense ones; a suite mixing tracks is refused."""
    raw = read_yaml(path)
    methods = _methods(raw.get("methods"), str(path))
    dense = [is_dense(m.method) for m in methods]
    if any(dense) and not all(dense):
        raise UserError(f"suite {path} mixes dense methods (projective, kdtree) with feature associators; "
                        "a dense run is scored differently: put them in separate suites")
    return all(dense)


def load_dense_suite(path: Path) -> DenseSuite:
    """Read and check a dense suite; every run is resolved now, so errors come before any render."""
    raw = read_yaml(path)
    unknown = [k for k in raw if k not in SUITE_KEYS]
    if unknown:
        raise UserError(f"unknown key {unknown[0]!r} in {path}; known keys: {', '.join(SUITE_KEYS)}")
    base = merge(defaults(), raw.get("base") or {}, f"{path} base")
    scenes = _list(raw, "scenes", [base["scene"]], str(path))
    seeds = _list(raw, "seeds", [base["seed"]], str(path))
    _refuse_duplicates(seeds, "seeds", str(path), "list each seed once")
    _refuse_duplicates(scenes, "scenes", str(path), "list each scene once")
    difficulties = _crossed(raw.get("difficulties") or {"default": {}}, raw.get("backends") or {})
    runs = []
    for scene in scenes:
        for name, override in difficulties.items():
            for m in _methods(raw.get("methods"), str(path)):
                for seed in seeds:
                    check_number(seed, f"seeds entry in {path}", integer=True, lo=0, hi=2**32 - 1)
                    cfg = base
                    for part in override if isinstance(override, list) else [override]:
                        cfg = merge(cfg, part or {}, f"{path} difficulty {name}")
                    cfg = merge(cfg, {"scene": scene, "seed": seed, "method": m.method, "params": m.params}, str(path))
                    runs.append((f"{Path(scene).stem}/{name}", m.label, int(seed), run_spec(cfg)))
    tolerance = check_number(raw.get("tolerance", 0.02), f"tolerance in {path}", lo=0)
    ate_tolerance = check_number(raw.get("ate_tolerance", 0.005), f"ate_tolerance in {path}", lo=0)
    return DenseSuite(path.stem, tuple(runs), float(tolerance), float(ate_tolerance))


def _render(spec: DenseRunSpec, cache_dir: str | None) -> None:
    from ..tracks.dense.sequence import load_dense_sequence

    load_dense_sequence(spec.sequence, Path(cache_dir) if cache_dir else None)


def _run(item: tuple, cache_dir: str | None) -> tuple[dict, pd.DataFrame, dict]:
    """One run in a worker: its summary row, its frames and a subsample of its map for the figure."""
    from .dense_execute import execute_dense
    from ..tracks.dense.plots import MAX_DRAWN

    scenario, label, seed, spec = item
    frames, summary, end = execute_dense(spec, Path(cache_dir) if cache_dir else None)
    step = max(1, len(end["map"]) // MAX_DRAWN)
    picture = {"positions": end["map"].positions[::step], "error_mm": 1000 * end["map_error"][::step],
               "p_true": frames[["true_x", "true_y", "true_z"]].to_numpy(float),
               "p_est": frames[["est_x", "est_y", "est_z"]].to_numpy(float)}
    frames.insert(0, "scenario", scenario)
    frames.insert(1, "method", label)
    frames.insert(2, "seed", seed)
    row = {"scenario": scenario, "method": label, "seed": seed, "tracking": spec.dense.tracking,
           **{k: summary[k] for k in DENSE_COLUMNS}}
    return row, frames, picture


def run_dense_suite(suite: DenseSuite, jobs: int = 1, cache_dir: Path | None = None,
                    progress: bool = True) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """Every run of ``suite``: summaries (one row a run), all frames, and map pictures by (scenario, label, seed)."""
    from tqdm import tqdm

    check_number(jobs, "--jobs", integer=True, lo=1, hi=256)
    cache = str(cache_dir) if cache_dir else None
    sequences = list({repr(spec.sequence): spec for _, _, _, spec in suite.runs}.values())   # each render once
    ctx = multiprocessing.get_context("spawn")   # a fresh GL context per worker; no forked EGL state
    with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
        list(tqdm(pool.map(_render, sequences, [cache] * len(sequences)), total=len(sequences),
                  desc="render depth", disable=not progress or None, leave=False))
        results = list(tqdm(pool.map(_run, suite.runs, [cache] * len(suite.runs)), total=len(suite.runs),
                            desc=f"dense {suite.name}", disable=not progress or None, leave=False))
    rows, frames, pictures = zip(*results)
    keys = [(sc, label, seed) for sc, label, seed, _ in suite.runs]
    return pd.DataFrame(rows), pd.concat(frames, ignore_index=True), dict(zip(keys, pictures))


def dense_table(summaries: pd.DataFrame) -> pd.DataFrame:
    """Mean over seeds per scenario × method; ``status`` is ok only when every seed's was."""
    numeric = [c for c in DENSE_COLUMNS if c not in ("status", "frames")]
    grouped = summaries.groupby(["scenario", "method"], sort=False)
    table = grouped[numeric].mean()
    table["status"] = grouped["status"].agg(lambda s: OK if (s == OK).all() else next(v for v in s if v != OK))
    table["seeds"] = grouped.size()
    table["frames"] = grouped["frames"].sum()
    return table.reset_index()


MD_COLUMNS = (("precision", "precision", "{:.3f}"), ("recall", "recall", "{:.3f}"),
              ("precision at start", "precision_start", "{:.3f}"), ("ICP failures", "icp_failures", "{:.1f}"),
              ("wrong steps", "wrong_steps", "{:.1f}"),
              ("ATE mm", "ate_mm", "{:.1f}"), ("final drift mm", "final_drift_mm", "{:.1f}"),
              ("step error mm / deg", ("step_error_mm", "step_error_deg"), "{:.2f} / {:.3f}"),
              ("map points", "map_points", "{:,.0f}"), ("compression %", "compression_pct", "{:.2f}"),
              ("map error mm median / p95", ("map_median_mm", "map_p95_mm"), "{:.1f} / {:.1f}"),
              ("ICP ms", "icp_ms", "{:.1f}"), ("fusion ms", "fusion_ms", "{:.1f}"))

MD_LEGEND = """Mean over seeds. Generated by `assocbench leaderboard --suite <suite>`. Each frame is tracked by
point-to-plane ICP from the previous estimate, pairing source points with pixels by the method, and
fused into a point map (the homework's point-based fusion); frame 0's pose is given.
*precision / recall*: of the pairs of ICP's last iteration against per-pixel truth (a pair is true when
map point and pixel lie on one geom with true positions within `dense.truth_tol`); *at start*: of its
first iteration, from the previous pose; *ICP failures*: frames whose ICP reported failure (pose held,
frame not fused); *ATE*: RMSE of the positions, no alignment; *step error*: RMS relative pose error of
one frame's step; *compression*: map points / (frames × pixels of the downsampled input), the homework's 8.87 %
definition; *map error*: distance of the map's points to the true surfaces.
"""


def _cell(r: pd.Series, col, fmt: str) -> str:
    values = [r[c] for c in (col if isinstance(col, tuple) else (col,))]
    return "–" if any(pd.isna(v) for v in values) else fmt.format(*values)


def dense_markdown(table: pd.DataFrame, title: str = "Dense leaderboard") -> str:
    """One section per scenario, a row per method (not-ok rows marked with their status)."""
    out = [f"# {title}", "", MD_LEGEND]
    for scenario, part in table.groupby("scenario", sort=False):
        out += [f"## {scenario}", "", "| method | " + " | ".join(h for h, _, _ in MD_COLUMNS) + " |",
                "|---" * (len(MD_COLUMNS) + 1) + "|"]
        for _, r in part.iterrows():
            name = r["method"] if r["status"] == OK else f"{r['method']} ({r['status']})"
            out.append(f"| {name} | " + " | ".join(_cell(r, c, f) for _, c, f in MD_COLUMNS) + " |")
        out.append("")
    return "\n".join(out)


def write_dense_leaderboard(summaries: pd.DataFrame, frames: pd.DataFrame, pictures: dict,
                            out: Path) -> dict[str, Path]:
    """``leaderboard.csv`` (every run), ``leaderboard.md``, ``frames.csv.gz``, ``leaderboard_map.png``:
    all written or none."""
    from ..atomic import write_group
    from ..tracks.dense.plots import map_figure

    table = dense_table(summaries)
    first_seed = {}
    for (scenario, label, seed), picture in pictures.items():
        first_seed.setdefault((scenario, label), picture | {"title": f"{label} on {scenario}, seed {seed}"})
    paths = {"csv": out / "leaderboard.csv", "md": out / "leaderboard.md", "frames": out / "frames.csv.gz",
             "map": out / "leaderboard_map.png"}
    write_group({paths["csv"]: lambda p: summaries.to_csv(p, index=False, float_format="%.6g"),
                 paths["md"]: lambda p: Path(p).write_text(dense_markdown(table)),
                 paths["frames"]: lambda p: frames.to_csv(p, index=False, float_format="%.6g", compression="gzip"),
                 paths["map"]: lambda p: map_figure(list(first_seed.values()), p, columns=4)})
    return paths


def compare_dense(table: pd.DataFrame, baseline: pd.DataFrame, suite: DenseSuite, tolerance: float) -> pd.DataFrame:
    """Findings that fail ``check``: a run not ok, precision or recall more than ``tolerance`` below
    the baseline, ATE or map error more than ``suite.ate_tolerance`` above it, a value not finite, a
    row missing on either side."""
    rows = []
    cur, base = table.set_index(["scenario", "method"]), baseline.set_index(["scenario", "method"])

    def finding(key, why, metric="", b=math.nan, c=math.nan):
        rows.append({"scenario": key[0], "method": key[1], "metric": metric, "baseline": b, "current": c,
                     "delta": c - b, "why": why})

    for key in suite.rows():
        if key not in base.index or key not in cur.index:
            finding(key, "not in the baseline (run check --update)" if key not in base.index else "not produced")
            continue
        if cur.loc[key, "status"] != OK:
            finding(key, f"run not ok: {cur.loc[key, 'status']}")
        for metric in HIGHER_BETTER + LOWER_BETTER_MM:
            b, c = float(base.loc[key, metric]), float(cur.loc[key, metric])
            worse = c < b - tolerance if metric in HIGHER_BETTER else c > b + 1000 * suite.ate_tolerance
            if not math.isfinite(c) or not math.isfinite(b):
                finding(key, "not a finite number", metric, b, c)
            elif worse:
                finding(key, "regressed", metric, b, c)
    for key in base.index:
        if key not in set(suite.rows()):
            finding(key, "in the baseline but not in the suite")
    return pd.DataFrame(rows, columns=["scenario", "method", "metric", "baseline", "current", "delta", "why"])


def read_dense_baseline(path: Path) -> pd.DataFrame:
    """A dense baseline CSV, or a one-line error naming what is wrong with it."""
    if not path.is_file():
        raise UserError(f"baseline {path} not found (create it with `assocbench check --suite <suite> --update`)")
    try:
        base = pd.read_csv(path, dtype={"scenario": str, "method": str})
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
        raise UserError(f"baseline {path} is not a readable CSV: {str(exc).strip().splitlines()[0]}") from None
    need = ["scenario", "method", *HIGHER_BETTER, *LOWER_BETTER_MM]
    missing = [c for c in need if c not in base.columns]
    if missing or base.empty:
        raise UserError(f"baseline {path} lacks columns {', '.join(missing) or '(no rows)'}; regenerate it with --update")
    for metric in need[2:]:
        values = pd.to_numeric(base[metric], errors="coerce")
        if not np.isfinite(values).all() or (values < 0).any():
            raise UserError(f"baseline {path}: {metric} holds a value that is not a finite number >= 0 (truncated "
                            "or edited?); regenerate it with --update")
        base[metric] = values
    return base


def write_dense_baseline(summaries: pd.DataFrame, path: Path) -> None:
    """Write the baseline (mean per scenario × method) atomically; refuse one from a run not ok."""
    write_ok_table(dense_table(summaries), ["scenario", "method", *HIGHER_BETTER, *LOWER_BETTER_MM], path)
