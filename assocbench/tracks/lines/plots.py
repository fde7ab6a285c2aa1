"""Top view of the lines track's closed loop, one panel per method: the walls (grey), the true path
(black), the estimate (blue), and the last frame drawn at the *estimated* pose: scan points and
segments coloured by what the method did (right wall green, wrong red, missed orange, clutter
purple). A misplaced estimate shows as scan offset from the walls.
"""

from __future__ import annotations

import json
from collections.abc import Mapping

import numpy as np
import pandas as pd

from ...models.se2 import rot2
from ...scoring.decisions import feature_decisions
from ...viz.loop_plots import label, method_order

STATUS_COLORS = {"right": "#2ca02c", "wrong": "#d62728", "missed": "#ff7f0e", "clutter": "#9467bd"}
FIGURE_WORDS = {"also": "right", "new": "missed"}   # the decisions this figure does not tell apart
ESTIMATE_COLOR = "#1f77b4"   # one colour in every panel: the status colours must stay unambiguous


def segment_status(labels: np.ndarray, landmark_ids: np.ndarray, association: np.ndarray, m: int) -> list[str]:
    """What the method did with each of the first ``m`` features: ``right`` (paired with its true
    line, or unpaired while another piece of that line was), ``wrong`` (another line), ``missed``
    (unpaired on a line nothing rightly paired with) or ``clutter`` (unpaired, on none).
    ``association[j]``: candidate j's feature."""
    labels = np.asarray(labels, np.int64)
    decided = feature_decisions(landmark_ids, labels, association, labels >= 0)[:m]
    return [FIGURE_WORDS.get(d, d) for d in decided]


def snapshot_json(pose: np.ndarray, points: np.ndarray, endpoints: np.ndarray, status: list[str]) -> str:
    """The last frame as drawn: estimated pose, scan points and segment ends (mm), each segment's
    status."""
    pts = np.asarray(points, float).reshape(-1, 2)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    return json.dumps({"pose": np.round(np.asarray(pose, float)[:3], 5).tolist(),
                       "points": np.round(pts, 3).tolist(),
                       "segments": np.round(np.asarray(endpoints, float).reshape(-1, 4), 3).tolist(),
                       "status": list(status)})


def _to_world(pose: np.ndarray, xy: np.ndarray) -> np.ndarray:
    return np.asarray(xy, float).reshape(-1, 2) @ rot2(pose[2]).T + np.asarray(pose[:2], float)


def _panel(ax, run: pd.DataFrame, segments: np.ndarray, snapshot: dict | None, color=ESTIMATE_COLOR) -> None:
    for s in segments:
        ax.plot(s[:, 0], s[:, 1], color="0.55", lw=1.6, solid_capstyle="butt", zorder=1)
    ax.plot(run["true_x"], run["true_y"], color="k", lw=2.2, zorder=2)
    ax.plot(run["est_x"], run["est_y"], color=color, lw=0.9, zorder=3)
    if snapshot:
        pose = np.array(snapshot["pose"], float)
        pts = _to_world(pose, snapshot["points"]) if snapshot["points"] else np.zeros((0, 2))
        ax.scatter(pts[:, 0], pts[:, 1], s=1.5, color="0.2", lw=0, zorder=4)
        for seg, status in zip(snapshot["segments"], snapshot["status"]):
            ends = _to_world(pose, np.reshape(seg, (2, 2)))
            ax.plot(ends[:, 0], ends[:, 1], color=STATUS_COLORS[status], lw=2.6, zorder=5)
        ax.plot(*pose[:2], marker="o", ms=4, color=color, zorder=6)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)


def line_map_figure(frames: pd.DataFrame, segments: np.ndarray, snapshots: Mapping[str, dict | None], title: str = ""):
    """The top view of one run per method: ``frames`` (one scenario and seed), ``segments`` (the
    walls' faces), ``snapshots`` (each method's last frame, or None)."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    order = method_order(frames["method"])
    segments = np.asarray(segments, float).reshape(-1, 2, 2)
    span = np.ptp(segments.reshape(-1, 2), axis=0) if len(segments) else np.ones(2)
    aspect = float(span[0] / max(span[1], 1e-9))   # a corridor is wide: one panel per row
    cols = min(max(len(order), 1), 1 if aspect > 4 else 2 if aspect > 2 else 3)
    rows = max(-(-len(order) // cols), 1)
    width = 12.6 / cols
    fig = Figure(figsize=(width * cols, (width / max(aspect, 0.5) + 0.6) * rows + 0.7))
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax in axes.flat[len(order):]:
        ax.axis("off")
    for ax, method in zip(axes.flat, order):
        run = frames[frames["method"] == method].sort_values("frame")
        _panel(ax, run, segments, snapshots.get(method))
        ax.set_title(label(method), fontsize=9)
    key = [Line2D([], [], color="0.55", lw=1.6, label="map wall"), Line2D([], [], color="k", lw=2.2, label="true path"),
           Line2D([], [], color=ESTIMATE_COLOR, lw=0.9, label="estimate")]
    key += [Line2D([], [], color=c, lw=2.6, label=f"last frame: {s}") for s, c in STATUS_COLORS.items()]
    fig.legend(handles=key, loc="lower center", ncol=len(key), fontsize=7, frameon=False)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 1 if not title else 0.95))
    return fig


def snapshots(frames: pd.DataFrame) -> dict[str, dict | None]:
    """Each method's last-frame snapshot from the ``final_scan`` column (None where not recorded)."""
    out: dict[str, dict | None] = {}
    for method, run in frames.groupby("method"):
        col = run.sort_values("frame")["final_scan"].dropna() if "final_scan" in run else pd.Series(dtype=object)
        out[method] = json.loads(col.iloc[-1]) if len(col) else None
    return out
