"""Top views of the dense track: fused maps coloured by their distance to the true surfaces, with
the true path (black), the estimate (blue), a red cross where ICP failed and an orange plus where
the method failed (pose held, frame not fused).

Each map point is rasterised into the panel's pixel grid, a pixel showing its worst error, so the
worst stay visible. Colours span the 2nd to 98th percentile of the figure's errors
(``colour_range``, one range for all panels).
"""

from __future__ import annotations

import gc
import textwrap
from collections.abc import Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .summary import METHOD_FAILED

PERCENTILES = (2.0, 98.0)   # the colour scale's ends, of the drawn points' errors
COLORMAP = "viridis"
DPI = 110
MARGIN = 0.03   # share of each span left around the map and paths, so no point sits on the frame
PANEL_WIDTH = 4.2    # inches a column of panels
AXES_WIDTH = 3.0     # inches of it a panel's axes get, beside the y label and the colour bar's share
MIN_AXES, MAX_AXES = 1.2, 3.0   # inches: a row's axes height, whatever the scene's aspect
LABEL_ROOM = 0.8     # inches a row needs besides its axes: the title above, the x label below
LEGEND_ROOM = 0.25   # inches at the top for the one legend
BAR_ROOM = 0.78      # inches at the bottom for the colour bar, across, and its label (two lines)
EMPTY_HEIGHT = 3.8   # inches of the figure that says no run produced a map
# short: all four entries fit in one row above a single 4.2 in panel; "pose held" is in the x label's note
FAILED_LABEL = "ICP failed"
RAISED_LABEL = "method failed"   # raised, hung or exited: the run's ``failures``
XLABEL_CHARS = 62   # an x label's line at 7 pt, within a panel's 4.2 in column (centred on its axes)


def view_limits(positions: np.ndarray, *paths: np.ndarray) -> tuple[float, float, float, float]:
    """``(x0, x1, y0, y1)`` (m) around every finite point and path, widened by ``MARGIN`` (1 m
    square for one point)."""
    xy = np.concatenate([np.asarray(a, float)[:, :2] for a in (positions, *paths)])
    xy = xy[np.isfinite(xy).all(axis=1)]
    if not len(xy):
        return -1.0, 1.0, -1.0, 1.0
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    span = float((hi - lo).max())
    pad = MARGIN * span if span > 0 else 0.5
    return float(lo[0] - pad), float(hi[0] + pad), float(lo[1] - pad), float(hi[1] + pad)


def worst_error_grid(xy: np.ndarray, error_mm: np.ndarray, extent: Sequence[float], width: int,
                     height: int) -> np.ndarray:
    """Per pixel the largest error (mm) of its points, ``-inf`` where none; row 0 at ``y0``."""
    x0, x1, y0, y1 = extent
    col = np.clip(((xy[:, 0] - x0) * (width / (x1 - x0))).astype(np.int64), 0, width - 1)
    row = np.clip(((xy[:, 1] - y0) * (height / (y1 - y0))).astype(np.int64), 0, height - 1)
    grid = np.full(width * height, -np.inf)
    np.maximum.at(grid, row * width + col, error_mm)
    return grid.reshape(height, width)


def colour_range(panels: Sequence[dict]) -> tuple[float, float]:
    """(lo, hi) mm: the ``PERCENTILES`` of every drawable error; (0, max(1, largest)) where they
    coincide."""
    errors = np.concatenate([p["error_mm"][_finite(p["positions"], p["error_mm"])] for p in panels] or [np.zeros(0)])
    if not len(errors):
        return 0.0, 1.0
    lo, hi = (float(v) for v in np.percentile(errors, PERCENTILES))
    return (lo, hi) if hi - lo > 1e-3 else (0.0, max(float(errors.max()), 1.0))


def error_colours(grid: np.ndarray, span: tuple[float, float]) -> np.ndarray:
    """RGBA ``(h, w, 4)`` of a worst-error grid in ``COLORMAP`` over ``span`` (as matplotlib picks
    it); transparent where empty."""
    from matplotlib import colormaps

    lo, hi = span
    lut = colormaps[COLORMAP].resampled(256)(np.arange(256), bytes=True)
    filled = np.isfinite(grid)
    level = np.clip((np.where(filled, grid, lo) - lo) * (256 / (hi - lo)), 0, 255).astype(np.intp)
    rgba = lut[level]
    rgba[~filled] = 0
    return rgba


def _frame_panel(ax, panel: dict) -> tuple[float, float, float, float]:
    """Paths, start mark, labels, title and limits of one panel; its extent (m)."""
    p_true, p_est = panel["p_true"], panel["p_est"]
    ax.plot(p_true[:, 0], p_true[:, 1], color="black", lw=2.0, label="true path")
    ax.plot(p_est[:, 0], p_est[:, 1], color="#1f77b4", lw=1.0, label="estimate")
    if len(p_true):
        ax.plot(*p_true[0, :2], "o", color="black", ms=4)
    failed, raised = _flagged_frames(panel, "failed"), _flagged_frames(panel, "raised")
    failed = failed & ~raised   # a raising method's frame is its own mark, not ICP's
    for mask, marker, colour, label in ((failed, "x", "#d62728", FAILED_LABEL), (raised, "+", "#ff7f0e", RAISED_LABEL)):
        if mask.any():   # above the paths: a held pose lies on the estimate, where a reader looks for it
            ax.plot(p_est[mask, 0], p_est[mask, 1], marker, color=colour, ms=5, mew=1.2, zorder=3, label=label)
    extent = view_limits(panel["positions"], p_true, p_est)
    ax.set_xlim(extent[:2])
    ax.set_ylim(extent[2:])
    ax.set_aspect("equal")
    xlabel = f"x (m){_lost_note(panel['positions'], panel['error_mm'])}{_failed_note(failed, raised)}"
    ax.set_xlabel(textwrap.fill(xlabel, XLABEL_CHARS), fontsize=7)   # notes can outgrow the panel: wrapped
    ax.set_ylabel("y (m)", fontsize=7)
    ax.set_title(textwrap.fill(panel["title"], 48), fontsize=8)   # a run's header is long: wrapped, not clipped
    ax.tick_params(labelsize=6)
    return extent


def _flagged_frames(panel: dict, key: str) -> np.ndarray:
    """(T,) flags ``key`` (``failed``: ICP, ``raised``: the method's call); none when absent."""
    flags = np.asarray(panel.get(key, np.zeros(len(panel["p_est"]), bool)), bool)
    if flags.shape != (len(panel["p_est"]),):
        raise ValueError(f"{key} has shape {flags.shape}, expected one flag per pose ({len(panel['p_est'])},)")
    return flags


def _failed_note(failed: np.ndarray, raised: np.ndarray) -> str:
    """The marks' counts over the tracked frames, as the summary counts them."""
    tracked = max(len(failed) - 1, 0)
    notes = [f"ICP failed in {int(failed.sum())} of {tracked} tracked frames (pose held)"] if failed.any() else []
    notes += [f"the method failed in {int(raised.sum())} of {tracked} (raised or hung; pose held)"] if raised.any() else []
    return "".join(f"; {n}" for n in notes)


def _finite(positions: np.ndarray, error_mm: np.ndarray) -> np.ndarray:
    return np.isfinite(positions[:, :2]).all(axis=1) & np.isfinite(error_mm)


def _lost_note(positions: np.ndarray, error_mm: np.ndarray) -> str:
    lost = int((~_finite(positions, error_mm)).sum())
    return f"; {lost:,} of {len(positions):,} map points not drawn (no finite x, y or error)" if lost else ""


def _raster_panel(ax, panel: dict, extent: tuple[float, float, float, float], span: tuple[float, float]) -> None:
    """The map points as an image in the axes' own pixel grid, beneath the paths."""
    ax.apply_aspect()
    box = ax.get_window_extent()
    width, height = max(1, int(box.width)), max(1, int(box.height))
    keep = _finite(panel["positions"], panel["error_mm"])
    grid = worst_error_grid(panel["positions"][keep, :2], panel["error_mm"][keep], extent, width, height)
    ax.imshow(error_colours(grid, span), extent=extent, origin="lower", interpolation="nearest", aspect="equal",
              zorder=0)


def map_figure(panels: Sequence[dict], path, columns: int = 3) -> None:
    """A PNG of one panel per entry (``positions``, ``error_mm``, ``p_true``, ``p_est``, ``title``,
    optional ``failed`` / ``raised`` flags); every finite point is drawn."""
    with _collector_paused():
        # the default zlib level: a faster one saves little and writes a bigger file
        map_canvas(panels, columns).savefig(path, dpi=DPI, format="png")


@contextmanager
def _collector_paused():
    """The garbage collector off while drawing: matplotlib's new objects would trigger a full
    collection (``benchmarks/dense_map_figure.py``)."""
    was_on = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_on:
            gc.enable()


def row_heights(panels: Sequence[dict], columns: int) -> list[float]:
    """Each row's axes height (inches): its tallest panel's aspect at ``AXES_WIDTH``, within
    [``MIN_AXES``, ``MAX_AXES``]."""
    cols = min(columns, len(panels)) or 1
    heights = []
    for first in range(0, len(panels), cols):
        aspects = []
        for panel in panels[first:first + cols]:
            x0, x1, y0, y1 = view_limits(panel["positions"], panel["p_true"], panel["p_est"])
            aspects.append((y1 - y0) / (x1 - x0))
        heights.append(float(np.clip(AXES_WIDTH * max(aspects), MIN_AXES, MAX_AXES)))
    return heights


def figure_size(panels: Sequence[dict], columns: int) -> tuple[float, float]:
    """(width, height) in inches: ``PANEL_WIDTH`` a column, the rows' heights plus label, legend and
    bar room."""
    if not panels:
        return PANEL_WIDTH, EMPTY_HEIGHT
    cols = min(columns, len(panels))
    heights = row_heights(panels, columns)
    height = LEGEND_ROOM + sum(heights) + LABEL_ROOM * len(heights) + BAR_ROOM
    return PANEL_WIDTH * cols, round(height * DPI) / DPI   # whole pixels: the PNG's size is the figure's


def map_canvas(panels: Sequence[dict], columns: int = 3):
    """``map_figure``'s ``Figure``: rows of panels, one legend above, one colour bar below."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure  # no pyplot state (as viz.plots)

    cols = min(columns, len(panels)) or 1
    rows = -(-len(panels) // cols) or 1
    width, height = figure_size(panels, columns)
    fig = Figure(figsize=(width, height), dpi=DPI)
    heights = row_heights(panels, columns) or [1.0]
    axes = fig.subplots(rows, cols, squeeze=False, gridspec_kw={"height_ratios": heights})
    if panels:   # in inches: the legend's strip at the top, each row's title above and x label below
        fig.subplots_adjust(top=1 - (LEGEND_ROOM + 0.45 * LABEL_ROOM) / height,
                            bottom=(BAR_ROOM + 0.55 * LABEL_ROOM) / height, hspace=LABEL_ROOM / float(np.mean(heights)),
                            left=0.6 / width, right=1 - 0.15 / width, wspace=1.0 / AXES_WIDTH)
    extents = [_frame_panel(ax, panel) for ax, panel in zip(axes.flat, panels)]
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    if not panels:   # every run failed before its map: say so rather than fail the leaderboard
        fig.text(0.5, 0.5, "no run produced a map", ha="center", va="center", fontsize=9)
    span = colour_range(panels)
    if panels:
        colours = ScalarMappable(norm=Normalize(*span), cmap=COLORMAP)
        # below the panels, across: a wide scene's single panel is barely an inch tall, too short
        # for a vertical bar's label, and a horizontal bar takes no panel's width
        bar_width = min(0.6, 3.0 / width)
        bar = fig.colorbar(colours, cax=fig.add_axes([0.5 - bar_width / 2, 0.48 / height, bar_width, 0.08 / height]),
                           orientation="horizontal")
        bar.set_label(f"distance to true surface (mm)\ncolours span its p{PERCENTILES[0]:g}\u2013p{PERCENTILES[1]:g}, "
                      f"{span[0]:.2g}\u2013{span[1]:.2g} mm (beyond: end colours)", fontsize=7, labelpad=2)
        bar.ax.tick_params(labelsize=6)
        # above the panels, not on one, where it would hide map points; every panel's entries (a
        # failure marker may be on any panel), each label once, in one row
        entries = {label: handle for ax in axes.flat for handle, label in zip(*ax.get_legend_handles_labels())}
        fig.legend(list(entries.values()), list(entries), loc="upper center", ncol=len(entries), fontsize=7,
                   frameon=False, bbox_to_anchor=(0.5, 1.0))
    for ax, panel, extent in zip(axes.flat, panels, extents):   # after the colour bar took its room
        _raster_panel(ax, panel, extent, span)
    return fig


def failure_flags(frames) -> dict:
    """A run's per-frame ``failed`` (ICP) and ``raised`` (the method's call) flags."""
    raised = frames["icp_reason"].eq(METHOD_FAILED).to_numpy() if "icp_reason" in frames else np.zeros(len(frames), bool)
    return {"failed": frames["icp_failed"].eq(True).to_numpy(), "raised": raised}


def map_writers(frames, map_file: Path, out: Path, title: str) -> dict:
    """Writers of ``map.ply`` and ``map.png`` from a run's frames and its worker's ``map.npz``."""
    from ...sim.ply import write_ply
    from .summary import poses

    with np.load(map_file) as z:
        m = {k: z[k] for k in z.files}
    p_true, p_est = poses(frames, "true_")[1], poses(frames, "est_")[1]
    panel = {"positions": m["positions"], "error_mm": m["error_mm"], "p_true": p_true, "p_est": p_est, "title": title,
             **failure_flags(frames)}
    return {out / "map.ply": lambda p: write_ply(p, m["positions"], m["normals"],
                                                 {"weight": m["weights"], "error_mm": m["error_mm"]}),
            out / "map.png": lambda p: map_figure([panel], p, columns=1)}
