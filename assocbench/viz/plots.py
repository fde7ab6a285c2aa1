"""The leaderboard's two plots (matplotlib, no pyplot state: safe in workers). Each method keeps one
look in both, a colour, a marker and a size growing with its rank by name, so coinciding methods
show as concentric marks.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..atomic import atomic_path

MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "p", "h", "*")
DPI = 110
MIN_SPAN = 0.05   # a zoomed precision or recall axis spans at least this much


def method_styles(methods) -> dict[str, dict]:
    """Matplotlib style of each method (sorted by name): ``color``, ``marker``, ``ms``."""
    return {m: {"color": f"C{k % 10}", "marker": MARKERS[k % len(MARKERS)], "ms": 5 + 2.5 * k}
            for k, m in enumerate(sorted(set(methods)))}


def zoom(values: np.ndarray, errors: np.ndarray) -> tuple[float, float]:
    """Axis limits around ``values ± errors`` with a margin, at least ``MIN_SPAN`` wide, within
    [-0.01, 1.01]; the whole unit interval when nothing is finite."""
    ends = np.concatenate([values - errors, values + errors])
    ends = ends[np.isfinite(ends)]
    if not len(ends):
        return -0.02, 1.02
    lo, hi = float(ends.min()), float(ends.max())
    pad = max(0.08 * (hi - lo), (MIN_SPAN - (hi - lo)) / 2, 0.01)
    lo, hi = max(lo - pad, -0.01), min(hi + pad, 1.01)
    if hi - lo < MIN_SPAN:   # against a wall of the unit square: widen the other way
        lo, hi = (hi - MIN_SPAN, hi) if hi >= 1.0 else (lo, lo + MIN_SPAN)
    return lo, hi


TIE_CHARS = 34      # a tie's words wrap at this many characters, so the list stays inside its panel
TIE_LINE_PT = 10.5  # points a line of a tie's words takes (7 pt text, its line spacing and descent)


def _ties(sub: pd.DataFrame) -> list[tuple[tuple[float, float], str]]:
    """Each point where methods' precision and recall agree to 3 decimals, and ``a = b = c``."""
    sub = sub[np.isfinite(sub["recall"]) & np.isfinite(sub["precision"])]
    key = list(zip(sub["recall"].round(3), sub["precision"].round(3)))
    groups = [(point, sorted(m for m, k in zip(sub["method"], key) if k == point)) for point in sorted(set(key))]
    return [(point, " = ".join(tied)) for point, tied in groups if len(tied) > 1]


def _emptiest_corner(ax, sub: pd.DataFrame, lines: int, near: tuple[float, float]) -> tuple[float, float]:
    """The panel corner whose box for ``lines`` lines holds the fewest points, nearest ``near``
    among those, so leaders stay short."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    fx = (sub["recall"].to_numpy(float) - x0) / (x1 - x0)
    fy = (sub["precision"].to_numpy(float) - y0) / (y1 - y0)
    tall = min(0.9, 0.06 * lines + 0.08)

    def count(corner):
        cx, cy = corner
        in_x = fx <= 0.6 if cx == 0 else fx >= 0.4
        in_y = fy >= 1 - tall if cy == 1 else fy <= tall
        return int(np.sum(in_x & in_y))

    nx, ny = (near[0] - x0) / (x1 - x0), (near[1] - y0) / (y1 - y0)
    return min([(0, 1), (1, 0), (1, 1), (0, 0)], key=lambda c: (count(c), np.hypot(c[0] - nx, c[1] - ny)))


def _name_ties(ax, sub: pd.DataFrame) -> None:
    """List ``a = b = c`` for methods tied to 3 decimals in the panel's emptiest corner, a thin
    leader to each point (beside the point the words overlapped)."""
    from matplotlib.transforms import offset_copy

    ties = [(point, textwrap.fill(words, TIE_CHARS, break_on_hyphens=False)) for point, words in _ties(sub)]
    if not ties:
        return
    lines = sum(words.count("\n") + 1 for _, words in ties)
    cx, cy = _emptiest_corner(ax, sub, lines, tuple(np.mean([point for point, _ in ties], axis=0)))
    down = 0.0
    for point, words in ties:
        where = offset_copy(ax.transAxes, fig=ax.figure, x=4 - 8 * cx, y=(-4 - down) if cy else (4 + down), units="points")
        ax.annotate(words, point, xytext=(cx, cy), textcoords=where, fontsize=7, color="0.25",
                    ha="right" if cx else "left", va="top" if cy else "bottom", annotation_clip=False,
                    arrowprops={"arrowstyle": "-", "color": "0.55", "lw": 0.6, "shrinkA": 1, "shrinkB": 3})
        down += TIE_LINE_PT * (words.count("\n") + 1) + 2


def _share_bars(mean: pd.Series, std: pd.Series) -> np.ndarray:
    """``± std`` as (below, above), cut at the ends of [0, 1]: past them a share's bar means nothing
    (and, drawn unclipped, it ran out of its panel into the legend)."""
    m, s = mean.to_numpy(float), std.to_numpy(float)
    return np.vstack([np.minimum(s, m), np.minimum(s, 1.0 - m)])


def _pr_panel(ax, sub: pd.DataFrame, styles: dict, title: str) -> None:
    """One scenario: each method's mean precision and recall, ± std bars (within [0, 1]), axes
    zoomed to them."""
    for method in sorted(sub["method"], key=lambda m: -styles[m]["ms"]):   # big marks behind
        r, st = sub[sub["method"] == method], styles[method]
        ax.errorbar(r["recall"], r["precision"], xerr=_share_bars(r["recall"], r["recall_std"]),
                    yerr=_share_bars(r["precision"], r["precision_std"]),
                    fmt=st["marker"], ms=st["ms"], color=st["color"], mfc="none", mew=1.5,
                    elinewidth=0.8, alpha=0.9, clip_on=False, label=method)
    ax.set(title=title, xlabel="recall", ylabel="precision",
           xlim=zoom(sub["recall"].to_numpy(float), sub["recall_std"].to_numpy(float)),
           ylim=zoom(sub["precision"].to_numpy(float), sub["precision_std"].to_numpy(float)))
    _name_ties(ax, sub)   # after the limits: it picks the panel's emptiest corner
    ax.grid(alpha=0.3)


def pr_figure(table: pd.DataFrame, scenes: Sequence[str], difficulties: Sequence[str]):
    """Precision against recall of a leaderboard table (``scenario`` = ``scene/difficulty``,
    means and ``_std`` columns): a row per scene, a column per difficulty, in the orders given."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    fig = Figure(figsize=(3.9 * len(difficulties), 3.5 * len(scenes)))
    axes = fig.subplots(len(scenes), len(difficulties), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    styles = method_styles(table["method"])
    for scenario, sub in table.groupby("scenario", sort=False):
        scene, _, difficulty = scenario.rpartition("/")
        ax = axes[list(scenes).index(scene), list(difficulties).index(difficulty)]
        ax.axis("on")
        _pr_panel(ax, sub, styles, scenario)
    handles = [Line2D([], [], ls="none", marker=st["marker"], ms=st["ms"], color=st["color"], mfc="none",
                      mew=1.5, label=m) for m, st in styles.items()]
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), frameon=False, fontsize=9)
    fig.text(0.5, 0.005, "mean ± std over seeds; each panel's axes are zoomed to its points (read the ticks); "
             "methods on the same spot show as concentric marks, named a = b in a corner", ha="center", va="bottom",
             fontsize=8)
    fig.tight_layout(rect=(0, 0.02, 1, 1 - 0.35 / (3.5 * len(scenes))))
    return fig


def binned_medians(n: np.ndarray, y: np.ndarray, bins: int = 12, min_count: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Median of ``y`` in ``bins`` equal bins of ``n``, NaN for a bin under ``min_count`` (a line
    breaks rather than joining unconnected clusters)."""
    edges = np.linspace(n.min(), n.max() + 1e-9, bins + 1)
    which = np.clip(np.digitize(n, edges) - 1, 0, bins - 1)
    mid_n, mid_y = (edges[:-1] + edges[1:]) / 2, np.full(bins, np.nan)
    for b in range(bins):
        if np.sum(which == b) >= min_count:
            mid_n[b], mid_y[b] = np.median(n[which == b]), np.median(y[which == b])
    return mid_n, mid_y


def runtime_figure(frames: pd.DataFrame):
    """``associate`` runtime against the number of candidates n (``method``, ``n``, ``runtime_s``
    per frame): every frame as a faint dot, and per method the median in bins of n."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.4, 4.2))
    ax = fig.subplots()
    for method, st in method_styles(frames["method"]).items():
        rows = frames[frames["method"] == method]
        n, ms = rows["n"].to_numpy(float), rows["runtime_s"].to_numpy(float) * 1e3
        ax.plot(n, ms, ".", ms=3.5, color=st["color"], alpha=0.3, mew=0)
        bn, bm = binned_medians(n, ms) if len(n) else (n, ms)
        ax.plot(bn, bm, "-", marker=st["marker"], ms=5, mfc="none", color=st["color"], lw=1.6, label=method)
    ax.set(xlabel="candidate landmarks n", ylabel="runtime per frame (ms)", yscale="log")
    ax.set_title("dots: frames; lines: median per bin of n (bins of 5 frames or more)", fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)   # beside: frames fill the axes
    fig.tight_layout()
    return fig


def figure_bytes(fig) -> bytes:
    """``fig`` as PNG bytes, as ``save_figure`` writes it."""
    import io

    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=DPI, format="png")
    return buffer.getvalue()


def save_figure(fig, path: Path) -> None:
    """Write ``fig`` as a PNG, atomically."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")
