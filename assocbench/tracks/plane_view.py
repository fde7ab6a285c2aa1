"""One frame of a robot in the plane, seen from above, as an RGB image: the map (grey), the true
path (black) and the estimate (blue), the scan (grey dots) and each feature coloured by what the
method decided, with a key counting each kind. The scan and features are drawn where the drawn
(estimated) pose puts them, so an estimate that is off shows as a scan shifted from the map.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..models.se2 import rot2

# what each kind of feature is called in the key, and its colour (the method's decisions, then the truth's)
FEATURE_KINDS = {
    "right": ("paired right", "#2ca02c"),
    "also": ("left out, its landmark paired to another", "#98df8a"),
    "wrong": ("paired wrong", "#d62728"),
    "missed": ("left out, its landmark predicted (missed)", "#ff7f0e"),
    "new": ("left out, landmark not predicted (new)", "#17becf"),
    "clutter": ("left out, no landmark (clutter)", "#9467bd"),
    "landmark": ("detection of a landmark", "#2ca02c"),
    "spurious": ("detection of no landmark", "#9467bd"),
}
MAP_COLOR, SCAN_COLOR, TRUE_COLOR, EST_COLOR, UNSEEN_COLOR = "0.55", "0.3", "k", "#1f77b4", "#ff7f0e"
TENTATIVE_COLOR = "#8c564b"   # a landmark not yet confirmed (brown: no decision's colour)
WIDTH_IN, DPI = 10.0, 100
AXES_LEFT, AXES_RIGHT = 0.075, 0.66   # the key sits right of the axes
MARGIN_M = 1.0


@dataclass
class PlaneFrame:
    """What one top view draws, in world metres; ``status`` names each feature's kind
    (``FEATURE_KINDS``), points first, then segments."""

    title: str
    bounds: tuple[float, float, float, float]   # x_min, x_max, y_min, y_max: fixed for a whole video
    true_path: np.ndarray                       # (k, 2) up to this frame
    true_pose: np.ndarray                       # (3,) x, y, θ
    scan: np.ndarray                            # (p, 2) the scan's hit points
    posts: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    walls: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    est_path: np.ndarray | None = None          # (k, 2)
    est_pose: np.ndarray | None = None          # (3,)
    est_joined: bool = True                     # a filter's path; False: independent draws (open loop)
    est_map: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))   # the filter's landmarks
    est_confirmed: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))   # each one confirmed
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))     # point features
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))   # line features
    status: list[str] = field(default_factory=list)
    kinds: tuple[str, ...] = ("right", "also", "wrong", "missed", "new", "clutter")   # in the key: decisions
    unseen_posts: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))     # detectable, not detected
    unseen_walls: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))  # extractable, not extracted
    note: str = ""                              # one line under the key (what is not drawn)


def to_world(pose: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Robot-frame points (k, 2) in the world: ``p_w = R(θ) p_r + (x, y)``."""
    return np.asarray(xy, float).reshape(-1, 2) @ rot2(float(pose[2])).T + np.asarray(pose[:2], float)


def plane_bounds(*points: np.ndarray, margin: float = MARGIN_M) -> tuple[float, float, float, float]:
    """The box around every finite point of ``points`` (each (k, 2) or (k, 2, 2)), widened by
    ``margin`` metres on every side."""
    xy = np.vstack([np.asarray(p, float).reshape(-1, 2) for p in points if np.size(p)] or [np.zeros((1, 2))])
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    lo, hi = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def figure_size(bounds: tuple[float, float, float, float]) -> tuple[float, float]:
    """Figure inches: fixed width, height from the box's aspect (a third to 1.2 of the width), at
    least the key's; even pixels (MP4)."""
    aspect = (bounds[3] - bounds[2]) / max(bounds[1] - bounds[0], 1e-9)
    axes_w = WIDTH_IN * (AXES_RIGHT - AXES_LEFT)
    height = max(float(np.clip(aspect, 1 / 3, 1.2)) * axes_w + 1.3, 5.0)
    return WIDTH_IN, 2 * round(height * DPI / 2) / DPI


def _pose_arrow(ax, pose: np.ndarray, color: str, length: float) -> None:
    ax.annotate("", xy=(pose[0] + length * np.cos(pose[2]), pose[1] + length * np.sin(pose[2])), xytext=pose[:2],
                arrowprops={"arrowstyle": "-|>", "color": color, "lw": 1.8}, zorder=9)
    ax.plot(*pose[:2], "o", color=color, ms=5, zorder=9)


def _draw_map(ax, f: PlaneFrame) -> None:
    from matplotlib.collections import LineCollection

    if len(f.walls):
        ax.add_collection(LineCollection(f.walls, colors=MAP_COLOR, linewidths=2.0, zorder=1))
    if len(f.unseen_walls):
        ax.add_collection(LineCollection(f.unseen_walls, colors=UNSEEN_COLOR, linewidths=4.0, alpha=0.5, zorder=1))
    if len(f.posts):
        ax.scatter(f.posts[:, 0], f.posts[:, 1], s=70, facecolors="none", edgecolors=MAP_COLOR, linewidths=1.4,
                   zorder=2)
    if len(f.unseen_posts):
        ax.scatter(f.unseen_posts[:, 0], f.unseen_posts[:, 1], s=150, facecolors="none", edgecolors=UNSEEN_COLOR,
                   linewidths=2.0, zorder=2)
    for confirmed, color in ((True, EST_COLOR), (False, TENTATIVE_COLOR)):
        xy = f.est_map[f.est_confirmed == confirmed]
        if len(xy):
            # larger than a feature's dot and over it: the cross's arms show round a detection paired with it
            ax.scatter(xy[:, 0], xy[:, 1], s=160, marker="+", color=color, linewidths=1.1, zorder=9)


def _draw_paths(ax, f: PlaneFrame, arrow: float) -> None:
    ax.plot(f.true_path[:, 0], f.true_path[:, 1], color=TRUE_COLOR, lw=2.0, zorder=4)
    if f.est_path is not None and len(f.est_path):
        style = {"lw": 1.2} if f.est_joined else {"ls": "none", "marker": ".", "ms": 3}
        ax.plot(f.est_path[:, 0], f.est_path[:, 1], color=EST_COLOR, zorder=5, **style)
    _pose_arrow(ax, f.true_pose, TRUE_COLOR, arrow)
    if f.est_pose is not None:
        _pose_arrow(ax, f.est_pose, EST_COLOR, arrow)


def _draw_features(ax, f: PlaneFrame) -> None:
    from matplotlib.collections import LineCollection

    scan = f.scan[np.all(np.isfinite(f.scan), axis=1)] if len(f.scan) else f.scan
    if len(scan):
        ax.scatter(scan[:, 0], scan[:, 1], s=2, color=SCAN_COLOR, lw=0, zorder=6)
    colors = [FEATURE_KINDS[s][1] for s in f.status]
    n = len(f.points)
    if n:
        ax.scatter(f.points[:, 0], f.points[:, 1], s=40, c=colors[:n], edgecolors="k", linewidths=0.5, zorder=8)
    if len(f.segments):
        ax.add_collection(LineCollection(f.segments, colors=colors[n:], linewidths=3.2, zorder=7))


def _key(fig, ax, f: PlaneFrame) -> None:
    from matplotlib.lines import Line2D

    counts = {k: f.status.count(k) for k in f.kinds}
    feature = {"marker": "o", "ls": "none", "ms": 7, "mec": "k"} if len(f.points) else {"lw": 3.2}
    handles = [Line2D([], [], color=FEATURE_KINDS[k][1], label=f"{FEATURE_KINDS[k][0]}: {counts[k]}", **feature)
               for k in f.kinds]
    handles += [Line2D([], [], color=SCAN_COLOR, marker=".", ls="none", ms=4, label="lidar scan"),
                Line2D([], [], color=TRUE_COLOR, lw=2.0, label="true path, pose")]
    if f.est_pose is not None:
        handles.append(Line2D([], [], color=EST_COLOR, lw=1.2 if f.est_joined else 0, marker=None if f.est_joined
                              else ".", label="estimated path, pose" if f.est_joined else "estimated pose, each frame"))
    if len(f.posts):
        handles.append(Line2D([], [], color=MAP_COLOR, marker="o", mfc="none", ls="none", ms=8, label="post (map)"))
    if len(f.walls):
        handles.append(Line2D([], [], color=MAP_COLOR, lw=2.0, label="wall (map)"))
    if len(f.est_map):
        handles.append(Line2D([], [], color=EST_COLOR, marker="+", ls="none", ms=11, mew=1.3, label="the filter's map"))
        if not np.all(f.est_confirmed):
            handles.append(Line2D([], [], color=TENTATIVE_COLOR, marker="+", ls="none", ms=11, mew=1.3,
                                  label="the filter's map, tentative"))
    if f.kinds == ("landmark", "spurious"):
        handles.append(Line2D([], [], color=UNSEEN_COLOR, marker="o", mfc="none", ls="none", ms=10, alpha=0.8,
                              label="detectable, not detected") if len(f.posts) else
                       Line2D([], [], color=UNSEEN_COLOR, lw=4.0, alpha=0.5, label="extractable, not extracted"))
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(AXES_RIGHT + 0.02, 0.9), fontsize=9,
               frameon=False, borderaxespad=0)
    if f.note:
        fig.text(AXES_RIGHT + 0.02, 0.04, f.note, fontsize=8, color="0.3", wrap=True, va="bottom")


def plane_view(f: PlaneFrame) -> np.ndarray:
    """The top view (module docstring) as an RGB image (H, W, 3) uint8; its size depends on
    ``f.bounds`` only, so every frame of a video has the same."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(plane_figure(f))
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def plane_figure(f: PlaneFrame):
    """The matplotlib ``Figure`` that ``plane_view`` draws."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figure_size(f.bounds), dpi=DPI)
    ax = fig.add_axes((AXES_LEFT, 0.1, AXES_RIGHT - AXES_LEFT, 0.78))
    x0, x1, y0, y1 = f.bounds
    arrow = 0.04 * max(x1 - x0, y1 - y0)
    _draw_map(ax, f)
    _draw_paths(ax, f, arrow)
    _draw_features(ax, f)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, color="0.92", lw=0.6, zorder=0)
    ax.tick_params(labelsize=8)
    fig.suptitle(f.title, fontsize=10, x=0.02, ha="left", y=0.985, va="top")
    _key(fig, ax, f)
    return fig
