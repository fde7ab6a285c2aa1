"""The closed-loop leaderboard's figures (matplotlib, no pyplot state): ``ate_figure`` (ATE per
method per scenario, ± std; the oracle hatched), ``nees_figure`` (median pose NEES over time against
its χ² band) and ``map_figure`` (one run's top view per method). Methods keep
``viz.plots.method_styles``' colours.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy.stats import chi2

from .plots import method_styles

ORACLE = "oracle"               # harness.config.ORACLE; viz does not import the harness
ORACLE_LABEL = "oracle (truth)"   # a simulated track's (``label``)
POSE_DOF = 6                    # NEES of a 6-DoF pose error
BAND = (0.025, 0.975)           # two-sided 95 % per frame
BOUND = 0.999                   # harness divergence test's level
LOG_RATIO = 20.0                # a panel whose ATEs span more than this ratio puts every panel on a log axis


def readable_log_axis(ax) -> None:
    """A log y axis in plain numbers, once the data are drawn: ticks at 1, 2, 5 × 10ᵏ over up to
    three decades, every (other) decade beyond, evenly spaced round values on a short span, so every
    panel keeps labelled ticks; the grid follows them."""
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter

    ax.set_yscale("log")
    low, high = ax.get_ylim()
    decades = np.log10(high / low) if low > 0 and high > low else 1.0
    subs = (1.0, 2.0, 5.0) if decades <= 3 else (1.0,)
    in_view = [t for t in LogLocator(subs=subs).tick_values(low, high) if low <= t <= high] if low > 0 else []
    ax.yaxis.set_major_locator(LogLocator(subs=subs, numticks=12) if len(in_view) >= 2 else MaxNLocator(4))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(NullFormatter())


def method_order(methods) -> list[str]:
    """``oracle`` first (the reference), then the others by name."""
    names = sorted(set(methods))
    return ([ORACLE] if ORACLE in names else []) + [m for m in names if m != ORACLE]


def label(method: str, scored_against: str = "truth") -> str:
    """A method's legend name: the oracle as ``oracle (truth)`` or, on a recorded track,
    ``oracle (reference)``."""
    return f"{ORACLE} ({scored_against})" if method == ORACLE else method


def scenario_grid(scenarios, scenes: Sequence[str] | None = None,
                  difficulties: Sequence[str] | None = None) -> tuple[list[str], list[str]]:
    """Rows (scenes) and columns (difficulties) of ``scene/difficulty`` names, in the orders given
    or of first appearance."""
    parts = [s.rpartition("/") for s in dict.fromkeys(scenarios)]
    scenes = list(scenes) if scenes is not None else list(dict.fromkeys(p[0] for p in parts))
    difficulties = list(difficulties) if difficulties is not None else list(dict.fromkeys(p[2] for p in parts))
    return scenes, difficulties


def _panels(scenarios, scenes, difficulties, width: float, height: float):
    """A figure with a row per scene and a column per difficulty; ``{scenario: ax}`` (unused panels off)."""
    from matplotlib.figure import Figure

    scenes, difficulties = scenario_grid(scenarios, scenes, difficulties)
    fig = Figure(figsize=(width * len(difficulties), height * len(scenes)))
    axes = fig.subplots(len(scenes), len(difficulties), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    out = {}
    for scenario in dict.fromkeys(scenarios):
        scene, _, difficulty = scenario.rpartition("/")
        ax = axes[scenes.index(scene), difficulties.index(difficulty)]
        ax.axis("on")
        out[scenario] = ax
    return fig, out


def _bar_style(method: str, styles: dict) -> dict:
    """Filled bars in the method's colour; the oracle hatched on white, so it reads as a reference."""
    if method == ORACLE:
        return {"facecolor": "white", "edgecolor": "0.3", "hatch": "///", "linewidth": 1.0}
    return {"facecolor": styles[method]["color"], "edgecolor": "none", "alpha": 0.85}


def wants_log(table: pd.DataFrame) -> bool:
    """Whether the ATE panels get a log axis: when one scenario's positive ATEs span more than
    ``LOG_RATIO`` (a diverged method would flatten the rest). One answer for every panel, so they
    share a scale."""
    for _, sub in table.groupby("scenario"):
        values = sub["ate_rmse"].to_numpy(float)
        positive = values[np.isfinite(values) & (values > 0)]
        if len(positive) > 1 and positive.max() > LOG_RATIO * positive.min():
            return True
    return False


def _ate_panel(ax, sub: pd.DataFrame, order: list[str], styles: dict, title: str, log: bool) -> None:
    """One scenario: a bar per method (in ``order``) at its mean ATE, ± std over seeds."""
    rows = sub.set_index("method")
    for x, method in enumerate(order):
        if method not in rows.index:
            continue
        mean, std = float(rows.at[method, "ate_rmse"]), float(rows.at[method, "ate_rmse_std"])
        if not np.isfinite(mean):
            ax.text(x, 0.02, "n/a", ha="center", va="bottom", fontsize=7, color="0.4",
                    transform=ax.get_xaxis_transform())   # at the panel's foot, on a linear or a log axis
            continue
        ax.bar(x, mean, 0.75, yerr=std if np.isfinite(std) else None, capsize=3,
               error_kw={"elinewidth": 0.9, "ecolor": "0.2"}, **_bar_style(method, styles))
    if log:
        readable_log_axis(ax)
    ax.set_xticks(range(len(order)), [label(m) for m in order], rotation=40, ha="right", fontsize=8)
    ax.set(title=title, ylabel="ATE (m)")
    ax.grid(axis="y", alpha=0.3, which="both")


def ate_figure(table: pd.DataFrame, scenes: Sequence[str] | None = None, difficulties: Sequence[str] | None = None,
               scored_against: str = "truth"):
    """ATE RMSE (m) per method per scenario (``scenario``, ``method``, ``ate_rmse``,
    ``ate_rmse_std``): a row of panels per scene, a column per difficulty, ± std bars; ``oracle``
    hatched and labelled (the filter fed the true association, the floor the others chase)."""
    from matplotlib.patches import Patch

    order = method_order(table["method"])
    styles = method_styles(table["method"])
    fig, axes = _panels(table["scenario"], scenes, difficulties, max(3.2, 0.45 * len(order) + 1.2), 3.4)
    log = wants_log(table)
    for scenario, ax in axes.items():
        _ate_panel(ax, table[table["scenario"] == scenario], order, styles, scenario, log)
    handles = [Patch(label=label(m, scored_against), **_bar_style(m, styles)) for m in order]
    fig.legend(handles=handles, loc="upper center", ncol=min(len(handles), 6), frameon=False, fontsize=8)
    scale = (f"log axes: a panel spans more than {LOG_RATIO:g}x" if log else "linear axes")
    against = "" if scored_against == "truth" else f" against the {scored_against} path"
    fig.text(0.5, 0.005, f"absolute trajectory error (RMSE of the position{against}, no alignment)\nbars: mean over "
             f"seeds, whiskers: ± std; every panel on {scale}",
             ha="center", va="bottom", fontsize=7)
    fig.tight_layout(rect=(0, 0.3 / fig.get_figheight(), 1, 1 - 0.5 / fig.get_figheight()))
    return fig


def nees_band(dof: int = POSE_DOF) -> tuple[float, float, float]:
    """(χ²_dof(0.025), χ²_dof(0.975), χ²_dof(0.999)): a consistent filter's per-frame NEES band and
    bound."""
    return float(chi2.ppf(BAND[0], dof)), float(chi2.ppf(BAND[1], dof)), float(chi2.ppf(BOUND, dof))


def median_over_seeds(frames: pd.DataFrame) -> pd.DataFrame:
    """Per method and frame the median ``nees`` over seeds (NaN frames left out)."""
    finite = frames[np.isfinite(frames["nees"].to_numpy(float))]
    return finite.groupby(["method", "frame"], as_index=False)["nees"].median()


def nees_figure(frames: pd.DataFrame, scenes: Sequence[str] | None = None, difficulties: Sequence[str] | None = None,
                scored_against: str = "truth"):
    """Pose NEES against frame: a panel per scenario, a line per method (median over seeds), log y,
    shaded the per-frame 95 % χ²_q band (q = ``nees_dof``), dashed χ²_q(0.999). Above the band:
    overconfident; on a recorded track the error is against the reference path."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    dof = int(frames["nees_dof"].dropna().iloc[0]) if "nees_dof" in frames and frames["nees_dof"].notna().any() \
        else POSE_DOF   # 3 for a pose in the plane, 6 in space (frames written before nees_dof: 6)
    lo, hi, bound = nees_band(dof)
    floor = lo / 20   # lower drawn at the bottom edge: a first frame's NEES of 5e-4 (a tight prior) took three decades
    order = method_order(frames["method"])
    styles = method_styles(frames["method"])
    fig, axes = _panels(frames["scenario"], scenes, difficulties, 4.4, 3.3)
    for scenario, ax in axes.items():
        med = median_over_seeds(frames[frames["scenario"] == scenario])
        ax.axhspan(lo, hi, color="0.85", zorder=0)
        ax.axhline(bound, color="0.3", ls="--", lw=1.0)
        for method in order:
            m = med[med["method"] == method]
            if len(m):
                ax.plot(m["frame"], np.maximum(m["nees"], floor), color=styles[method]["color"], lw=1.4,
                        ls=":" if method == ORACLE else "-")
        ax.set(title=scenario, xlabel="frame", ylabel="pose NEES")
        ax.set_yscale("log")
        ax.set_ylim(bottom=floor / 1.3)
        readable_log_axis(ax)
        ax.grid(alpha=0.3, which="major")
    handles = [Line2D([], [], color=styles[m]["color"], lw=1.4, ls=":" if m == ORACLE else "-",
                      label=label(m, scored_against)) for m in order]
    handles += [Patch(color="0.85", label=f"per-frame 95 % band of $\\chi^2_{dof}$"),
                Line2D([], [], color="0.3", ls="--", label=f"$\\chi^2_{dof}$(0.999)")]
    fig.legend(handles=handles, loc="upper center", ncol=min(len(handles), 5), frameon=False, fontsize=8)
    fig.text(0.5, 0.005, "median over seeds per frame; above the band: overconfident, below: conservative; "
             f"values below {floor:.2g} drawn at {floor:.2g}",
             ha="center", va="bottom", fontsize=7)
    fig.tight_layout(rect=(0, 0.03, 1, 1 - 0.55 / fig.get_figheight()))
    return fig


def _map_limits(frames: pd.DataFrame, landmarks, maps) -> tuple[tuple[float, float], tuple[float, float]]:
    """x and y limits holding every finite point drawn, with a 5 % margin (at least 0.1 m)."""
    xy = [frames[["true_x", "true_y"]].to_numpy(float), frames[["est_x", "est_y"]].to_numpy(float)]
    xy += [np.asarray(a, float)[:, :2] for a in ([landmarks] if landmarks is not None else [])
           + list((maps or {}).values()) if len(a)]
    pts = np.vstack(xy)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if not len(pts):
        return (-1.0, 1.0), (-1.0, 1.0)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = np.maximum(0.05 * (hi - lo), 0.1)
    return (lo[0] - pad[0], hi[0] + pad[0]), (lo[1] - pad[1], hi[1] + pad[1])


def _map_panel(ax, run: pd.DataFrame, landmarks, means, color, limits) -> None:
    """One method's run: true landmarks, its final map, the true path (thick) and its estimate (thin)."""
    if landmarks is not None and len(landmarks):
        ax.plot(np.asarray(landmarks)[:, 0], np.asarray(landmarks)[:, 1], ".", color="0.6", ms=3)
    if means is not None and len(means):
        ax.plot(np.asarray(means)[:, 0], np.asarray(means)[:, 1], "+", color=color, ms=4, mew=0.8)
    ax.plot(run["true_x"], run["true_y"], "-", color="0.1", lw=2.2)
    if "odo_x" in run and np.isfinite(run["odo_x"].to_numpy(dtype=float)).any():   # odometry alone, where recorded
        ax.plot(run["odo_x"], run["odo_y"], "--", color="0.45", lw=0.9)
    ax.plot(run["est_x"], run["est_y"], "-", color=color, lw=1.0)
    ax.set(xlim=limits[0], ylim=limits[1], xlabel="x (m)", ylabel="y (m)")
    ax.set_aspect("equal", adjustable="box")
    ax.grid(alpha=0.3)


def map_figure(frames: pd.DataFrame, landmarks: np.ndarray | None = None,
               maps: Mapping[str, np.ndarray] | None = None, title: str = "", scored_against: str = "truth"):
    """Top view (metres, equal axes) of one run per method: ``frames`` (one scenario and seed with
    ``true_x/y``, ``est_x/y``), ``landmarks`` (grey), ``maps`` (each method's final map; without
    them trajectories only, and the figure says so); ``scored_against`` names what is drawn."""
    from matplotlib.figure import Figure

    order = method_order(frames["method"])
    styles = method_styles(frames["method"])
    cols = min(max(len(order), 1), 4)
    rows = max(-(-len(order) // cols), 1)
    fig = Figure(figsize=(3.4 * cols, 3.5 * rows + 0.5))
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax in axes.flat[len(order):]:
        ax.axis("off")
    limits = _map_limits(frames, landmarks, maps)   # one box for every panel, so they compare
    for ax, method in zip(axes.flat, order):
        _map_panel(ax, frames[frames["method"] == method].sort_values("frame"), landmarks,
                   None if maps is None else maps.get(method), styles[method]["color"], limits)
        ax.set_title(label(method, scored_against), fontsize=9)
    word = "true" if scored_against == "truth" else scored_against
    what = f"thick black: {word} path; thin: estimate" + (f"; grey dots: {word} landmarks" if landmarks is not None
                                                           else "")
    if "odo_x" in frames and np.isfinite(frames["odo_x"].to_numpy(dtype=float)).any():
        what += "; dashed: odometry alone"
    what += "; +: final map" if maps is not None else "; map not recorded (trajectories only)"
    fig.suptitle(title, fontsize=10)
    fig.text(0.5, 0.005, what, ha="center", va="bottom", fontsize=7)
    fig.tight_layout(rect=(0, 0.03, 1, 1 if not title else 0.95))
    return fig


def final_maps(frames: pd.DataFrame) -> dict[str, np.ndarray] | None:
    """Each method's final confirmed map from its last frame's ``final_map``; None when not
    recorded."""
    if "final_map" not in frames:
        return None
    out = {}
    for method, run in frames.groupby("method"):
        last = run.sort_values("frame")["final_map"].dropna()
        out[method] = np.array(json.loads(last.iloc[-1]), dtype=float).reshape(-1, 2) if len(last) else np.zeros((0, 2))
    return out


def landmark_map_figure(frames: pd.DataFrame, landmarks: np.ndarray, title: str = "", scored_against: str = "truth"):
    """``map_figure`` of one seed's closed-loop ``frames`` over the true (or reference) ``landmarks``
    (x, y first), with each method's final map (``final_maps``)."""
    return map_figure(frames, landmarks, final_maps(frames), title=title, scored_against=scored_against)
