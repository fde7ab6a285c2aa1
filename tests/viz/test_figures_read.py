"""Every kind of figure that ``run``, ``frame``, ``render``, ``leaderboard`` and ``report`` draw with
matplotlib reads (``figure_checks``): no text over another, no legend over the data, no text out of
the figure or an annotation out of its panel, one scale for panels of one quantity. Drawn from
small synthetic data, and from the committed leaderboards where a figure is drawn from their table."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from figure_checks import assert_reads, problems

from assocbench.harness.leaderboard import _grid, order_scenarios
from assocbench.scoring.aggregate import leaderboard_table
from assocbench.tracks.dense.plots import map_canvas
from assocbench.tracks.lines.plots import line_map_figure
from assocbench.tracks.plane_view import PlaneFrame, plane_figure
from assocbench.viz.cd_diagram import cd_figure
from assocbench.viz.loop_plots import ate_figure, map_figure, nees_figure
from assocbench.viz.plots import pr_figure, runtime_figure

RESULTS = Path(__file__).resolve().parents[2] / "results"
METHODS = ("ccda", "enn", "jcbb", "jpda", "learned", "lsa", "ml", "mnn", "rjc", "snn")
SCENARIOS = [f"{s}/{d}" for s in ("checkerboard", "corridor", "room") for d in ("easy", "medium", "hard")]


def _summaries() -> pd.DataFrame:
    """Two seeds of ten methods in nine scenarios; in the easy ones most methods tie near
    precision and recall 1 (the right edge of the panel), in two groups."""
    rng = np.random.default_rng(5)
    rows = []
    for sc in SCENARIOS:
        for j, m in enumerate(METHODS):
            for seed in (0, 1):
                if sc.endswith("easy"):
                    p, r = (0.998, 0.999) if j % 3 else (0.997, 0.991)
                else:
                    p, r = 0.5 + 0.4 * rng.random(), 0.4 + 0.5 * rng.random()
                rows.append({"scenario": sc, "method": m, "seed": seed, "status": "ok", "precision": p, "recall": r,
                             "f1": 2 * p * r / (p + r), "perfect": 0.5, "surprisal_gap": 1.0,
                             "runtime_median_ms": 0.2, "frames": 10, "failures": 0, "timed_out": 0})
    return pd.DataFrame(rows)


def _pr(table: pd.DataFrame):
    table = order_scenarios(table)
    return pr_figure(table, *_grid(table, ()))


@pytest.mark.parametrize("source", ["synthetic", "leaderboard.csv", "loop", "planar", "lines"])
def test_precision_recall(source):
    table = (leaderboard_table(_summaries()) if source == "synthetic" else
             pd.read_csv(RESULTS / (source if source.endswith(".csv") else f"{source}/leaderboard.csv")))
    assert_reads(_pr(table))


def test_runtime():
    rng = np.random.default_rng(2)
    n = np.r_[rng.integers(10, 16, 400), rng.integers(40, 56, 400)]
    frames = pd.concat([pd.DataFrame({"method": m, "n": n, "runtime_s": 1e-4 * (1 + k) * (1 + n / 10)
                                      * rng.lognormal(0, 0.5, len(n))}) for k, m in enumerate(METHODS)])
    assert_reads(runtime_figure(frames))


@pytest.mark.parametrize("source", ["synthetic", "loop", "planar", "lines"])
def test_ate(source):
    if source == "synthetic":   # one panel spans more than 20x (a diverged method), its neighbours do not
        rows = [{"scenario": sc, "method": m, "ate_rmse": a * (40 if sc == "room/medium" and m == "mnn" else 1),
                 "ate_rmse_std": a / 5} for sc in SCENARIOS for m, a in (("oracle", 0.02), ("jcbb", 0.03),
                                                                         ("mnn", 0.05))]
        table = pd.DataFrame(rows)
    else:
        table = pd.read_csv(RESULTS / source / "leaderboard.csv")
    table = order_scenarios(table)
    assert_reads(ate_figure(table, *_grid(table, ())))


def test_nees():
    rng = np.random.default_rng(7)
    rows = [{"scenario": sc, "method": m, "seed": s, "frame": k, "nees": float(rng.chisquare(6)) * (1 + (m == "mnn") * k),
             "nees_dof": 6} for sc in SCENARIOS[:6] for m in ("oracle", "jcbb", "mnn", "learned")
            for s in range(2) for k in range(30)]
    frames = pd.DataFrame(rows)
    assert_reads(nees_figure(frames, *_grid(frames, ())))


def _loop_frames(methods) -> pd.DataFrame:
    t = np.linspace(0, 2 * np.pi, 40)
    return pd.DataFrame([{"method": m, "frame": k, "true_x": 3 * np.cos(a), "true_y": 2 * np.sin(a),
                          "est_x": 3 * np.cos(a) + 0.01 * k * j, "est_y": 2 * np.sin(a), "odo_x": 3.2 * np.cos(a),
                          "odo_y": 2.1 * np.sin(a)} for j, m in enumerate(methods) for k, a in enumerate(t)])


def test_loop_map():
    landmarks = np.array([[x, y, 0.0] for x in np.linspace(-4, 4, 6) for y in (-3.0, 3.0)])
    methods = ("oracle", "jcbb", "mnn", "lsa", "learned")
    fig = map_figure(_loop_frames(methods), landmarks, {m: landmarks[:, :2] + 0.05 for m in methods},
                     title="park/hard-ekf seed 0")
    assert_reads(fig)


def test_lines_map():
    segments = np.array([[[-4, -3], [4, -3]], [[4, -3], [4, 3]], [[4, 3], [-4, 3]], [[-4, 3], [-4, -3]],
                         [[-0.1, -0.1], [0.7, -0.1]]], float)
    methods = ("oracle", "jcbb", "mnn", "lsa", "learned", "enn", "ml")
    snap = {"pose": [3.0, 0.0, 1.5], "points": [[1.0, 0.0], [1.0, 0.2]], "segments": [[1.0, -0.5, 1.0, 0.5]],
            "status": ["right"]}
    assert_reads(line_map_figure(_loop_frames(methods), segments, {m: snap for m in methods},
                                 title="office/hard-ransac seed 0"))


def _dense_panel(scene: str, k: int) -> dict:
    rng = np.random.default_rng(k)
    size = (9.0, 3.6) if scene == "bays" else (2.2, 3.6)
    pts = np.column_stack([rng.uniform(0, size[0], 4000), rng.uniform(-size[1] / 2, size[1] / 2, 4000),
                           np.zeros(4000)])
    path = np.column_stack([np.linspace(0.5, 1.5, 30), np.zeros(30), np.zeros(30)])
    failed = np.zeros(30, bool)
    failed[[5, 9]] = True
    return {"positions": pts, "error_mm": rng.gamma(1.5, 1.2, 4000), "p_true": path, "p_est": path + 0.01,
            "title": f"projective on {scene}/default-model, seed {k}", "failed": failed, "raised": np.roll(failed, 3)}


@pytest.mark.parametrize("scenes,columns", [(("crates",), 1), (("bays", "bays", "crates", "crates"), 4)])
def test_dense_map(scenes, columns):
    assert_reads(map_canvas([_dense_panel(s, k) for k, s in enumerate(scenes)], columns))


def test_plane_view():
    posts = np.array([[x, y] for x in range(-4, 5, 2) for y in (-3.0, 3.0)], float)
    status = ["right", "wrong", "missed", "new", "clutter", "also"]
    frame = PlaneFrame("park hard frame 12 | jcbb | closed loop, ekf slam\n5 right, 1 wrong, 1 missed pairings",
                       (-6.0, 6.0, -5.0, 5.0), np.column_stack([np.linspace(-3, 0, 12), np.zeros(12)]),
                       np.array([0.0, 0.0, 0.3]), np.random.default_rng(1).uniform(-4, 4, (200, 2)), posts=posts,
                       est_path=np.column_stack([np.linspace(-3, 0.1, 12), np.full(12, 0.05)]),
                       est_pose=np.array([0.1, 0.05, 0.31]), est_map=posts[:6] + 0.05,
                       est_confirmed=np.array([True] * 5 + [False]), points=posts[:6] + 0.1, status=status,
                       note="the scan and features are drawn at the estimated pose")
    assert_reads(plane_figure(frame))


@pytest.mark.parametrize("k", [2, 4, 12])
def test_critical_difference_diagram(k):
    names = [f"{m}" for m in (METHODS + ("mypkg.assoc:Mine", "naive16"))[:k]]
    ranks = np.linspace(1.4, k - 0.3, k)
    assert_reads(cd_figure(names, ranks, 1.1, [(0, 1), (1, 2)] if k > 2 else [], "Camera, open loop",
                           "Friedman p = 0.0031, 27 blocks"))


def test_the_checker_finds_what_it_should():
    """Each check fails on a figure made to fail it: texts drawn over one another, a legend on the
    data, a title out of the figure, log beside linear panels of one quantity."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4, 3))
    left, right = fig.subplots(1, 2)
    for ax in (left, right):
        ax.plot(np.linspace(0, 1, 50), np.linspace(0, 1, 50) ** 2 + 0.01, label="data")
        ax.set_ylabel("ATE (m)")
    right.set_yscale("log")
    left.text(0.5, 0.5, "one", transform=left.transAxes)
    left.text(0.52, 0.5, "two", transform=left.transAxes)
    left.legend(loc="center")
    fig.text(0.9, 0.5, "far out to the right of everything")
    found = "\n".join(problems(fig))
    assert "overlaps text" in found and "a legend covers the lines" in found
    assert "leaves the figure" in found and "mix linear and log scales" in found
