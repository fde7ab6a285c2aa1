"""Top views of the dense track: fused maps coloured by their distance to the true surfaces,
with the true path (black) and the estimated one (blue).

A map point is drawn at its (x, y); points are sorted so the worst are drawn last and stay
visible. The colour scale is fixed (0 to ``ERROR_SCALE_MM``) so panels compare at a glance.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path

import numpy as np

ERROR_SCALE_MM = 30.0
# points drawn per panel (an even subsample beyond it: a PNG, not an archive): a panel is about
# 460 x 420 px, so more points only overdraw; 150 000 cost 0.9 s a run (issue 27), 40 000 0.67 s, 18 000 0.46 s (load 4)
MAX_DRAWN = 20_000


def map_panel(ax, positions: np.ndarray, error_mm: np.ndarray, p_true: np.ndarray, p_est: np.ndarray,
              title: str):
    """One top view: map points coloured by error, true and estimated paths; the scatter's handle.
    At most ``MAX_DRAWN`` points, every ``step``-th with ``step = ⌈N / MAX_DRAWN⌉`` (the floor drew
    up to twice as many), and the x label says so when not all are drawn."""
    step = max(1, -(-len(positions) // MAX_DRAWN))
    pos, err = positions[::step], error_mm[::step]
    order = np.argsort(err)
    sc = ax.scatter(pos[order, 0], pos[order, 1], c=err[order], s=0.5, cmap="viridis", vmin=0,
                    vmax=ERROR_SCALE_MM, linewidths=0, rasterized=True)
    ax.plot(p_true[:, 0], p_true[:, 1], color="black", lw=2.0, label="true path")
    ax.plot(p_est[:, 0], p_est[:, 1], color="#1f77b4", lw=1.0, label="estimate")
    ax.plot(*p_true[0, :2], "o", color="black", ms=4)
    ax.set_aspect("equal")
    drawn = "" if step == 1 else f"; {len(pos):,} of {len(positions):,} map points drawn (1 in {step})"
    ax.set_xlabel(f"x (m){drawn}", fontsize=7)
    ax.set_ylabel("y (m)", fontsize=7)
    ax.set_title(textwrap.fill(title, 48), fontsize=8)   # a run's header is long: wrapped, not clipped
    ax.tick_params(labelsize=6)
    return sc


def map_figure(panels: Sequence[dict], path, columns: int = 3) -> None:
    """A PNG of one panel per entry (``positions``, ``error_mm``, ``p_true``, ``p_est``, ``title``)."""
    from matplotlib.figure import Figure  # no pyplot state (as viz.plots)

    cols = min(columns, len(panels))
    rows = -(-len(panels) // cols)
    fig = Figure(figsize=(4.2 * cols, 3.8 * rows))
    axes = fig.subplots(rows, cols, squeeze=False)
    sc = None
    for ax, panel in zip(axes.flat, panels):
        sc = map_panel(ax, panel["positions"], panel["error_mm"], panel["p_true"], panel["p_est"], panel["title"])
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    if sc is not None:
        bar = fig.colorbar(sc, ax=axes, shrink=0.6, fraction=0.03, pad=0.02)
        bar.set_label(f"distance to true surface, mm (clipped at {ERROR_SCALE_MM:g})", fontsize=7)
        bar.ax.tick_params(labelsize=6)
        axes.flat[0].legend(fontsize=6, loc="upper right", markerscale=4)
    fig.savefig(path, dpi=110)


def map_writers(frames, map_file: Path, out: Path, title: str) -> dict:
    """Writers of ``map.ply`` and ``map.png`` from a run's frames and its worker's ``map.npz``."""
    from ...sim.ply import write_ply
    from .summary import poses

    with np.load(map_file) as z:
        m = {k: z[k] for k in z.files}
    p_true, p_est = poses(frames, "true_")[1], poses(frames, "est_")[1]
    panel = {"positions": m["positions"], "error_mm": m["error_mm"], "p_true": p_true, "p_est": p_est, "title": title}
    return {out / "map.ply": lambda p: write_ply(p, m["positions"], m["normals"],
                                                 {"weight": m["weights"], "error_mm": m["error_mm"]}),
            out / "map.png": lambda p: map_figure([panel], p, columns=1)}
