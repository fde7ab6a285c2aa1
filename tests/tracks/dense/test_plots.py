"""The dense map's top view rasterises every map point into the panel's pixels, the worst error
of a pixel on top, and writes a PNG of the figure's size."""

from __future__ import annotations

import gc

import numpy as np
import pandas as pd
import pytest
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from PIL import Image

from assocbench.tracks.dense.plots import (
    DPI,
    FAILED_LABEL,
    MAX_AXES,
    MIN_AXES,
    RAISED_LABEL,
    colour_range,
    error_colours,
    failure_flags,
    figure_size,
    map_canvas,
    map_figure,
    row_heights,
    view_limits,
    worst_error_grid,
)
from assocbench.tracks.dense.summary import METHOD_FAILED

PATH = np.column_stack([np.linspace(0.0, 1.0, 20), np.zeros(20), np.zeros(20)])


def panel(positions, error_mm, title="projective on crates, seed 0"):
    return {"positions": np.asarray(positions, float), "error_mm": np.asarray(error_mm, float),
            "p_true": PATH, "p_est": PATH + 0.01, "title": title}


@pytest.mark.parametrize("errors", [[5.0, 25.0, 12.0], [25.0, 12.0, 5.0], [12.0, 5.0, 25.0]])
def test_the_worst_point_of_a_pixel_is_drawn_whatever_the_order(errors):
    xy = np.array([[0.51, 0.52], [0.52, 0.51], [0.505, 0.515]])   # one pixel of a 10 x 10 grid over 1 m
    grid = worst_error_grid(xy, np.array(errors), (0.0, 1.0, 0.0, 1.0), 10, 10)
    assert grid[5, 5] == 25.0
    assert np.isinf(np.delete(grid.ravel(), 55)).all()


def test_every_point_lands_inside_the_grid_edges_included():
    """Points on the extent's far edges fall in the last column/row, not outside (or wrapped)."""
    xy = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 1.0], [2.0, 1.0], [1.0, 0.5]])
    grid = worst_error_grid(xy, np.arange(1.0, 6.0), (0.0, 2.0, 0.0, 1.0), 8, 4)
    assert grid[0, 0] == 1.0 and grid[0, 7] == 2.0 and grid[3, 0] == 3.0 and grid[3, 7] == 4.0
    assert grid[2, 4] == 5.0 and np.isfinite(grid).sum() == 5


def test_every_point_counts_a_hundred_thousand_in_distinct_pixels():
    """The old picture drew 1 in 5 of a 100k-point map; here each point owns its pixel."""
    cols, rows = np.meshgrid(np.arange(400), np.arange(250))
    xy = np.column_stack([cols.ravel() + 0.5, rows.ravel() + 0.5]) / 100.0
    grid = worst_error_grid(xy, np.full(len(xy), 7.0), (0.0, 4.0, 0.0, 2.5), 400, 250)
    assert np.isfinite(grid).all() and len(xy) == 100_000


def test_colours_are_the_ones_the_colour_bar_gives_and_empty_pixels_are_transparent():
    values = np.array([0.0, 0.5, 1.3, 7.3, 11.99, 12.0, 120.0])
    rgba = error_colours(np.append(values, -np.inf).reshape(1, -1), (0.5, 12.0))
    assert rgba.dtype == np.uint8 and rgba.shape == (1, 8, 4)
    bar = ScalarMappable(norm=Normalize(0.5, 12.0), cmap="viridis")
    assert (rgba[0, :7] == bar.to_rgba(values, bytes=True)).all()
    assert (rgba[0, 7] == 0).all()


def test_the_colour_scale_spans_the_maps_errors_not_a_fixed_30_mm():
    """The committed dense picture was one colour: a crates map's errors are mostly under 2 mm, on a
    0-30 mm scale. The scale spans the 2nd to 98th percentile of every panel's drawable errors, and
    the colour bar says so."""
    rng = np.random.default_rng(4)
    errors = [rng.gamma(1.5, 0.6, 5000), rng.gamma(1.5, 0.9, 5000)]
    pts = rng.uniform(0, 2, (5000, 3))
    panels = [panel(pts, e) for e in errors]
    panels[1]["error_mm"][:10] = np.nan   # not drawn: not counted
    lo, hi = np.percentile(np.concatenate([errors[0], errors[1][10:]]), [2, 98])
    assert colour_range(panels) == pytest.approx((lo, hi)) and hi < 10
    fig = map_canvas(panels, columns=2)
    bar = fig.axes[-1]
    assert bar.get_xlim() == pytest.approx((lo, hi))
    assert "p2\u2013p98" in bar.get_xlabel() and f"{hi:.2g} mm" in bar.get_xlabel()
    drawn = np.asarray(fig.axes[0].get_images()[0].get_array())
    levels = {tuple(c) for c in drawn[drawn[..., 3] > 0][:, :3]}
    assert len(levels) > 50   # many colours, not one
    assert colour_range([panel([[0.5, 0.3, 0.0]], [99.0])]) == (0.0, 99.0)   # one point: from 0 to it


def test_limits_cover_map_and_paths_with_a_margin():
    x0, x1, y0, y1 = view_limits(np.array([[3.0, -2.0, 0.0], [np.nan, 9.0, 0.0]]), PATH)
    assert x0 < 0.0 and x1 > 3.0 and y0 < -2.0 and y1 > 0.0 and x1 < 4.0
    assert view_limits(np.zeros((0, 3)), np.zeros((0, 3))) == (-1.0, 1.0, -1.0, 1.0)


def test_png_has_the_figure_size_and_a_point_sits_where_the_axes_put_it(tmp_path):
    """One point of error beyond the scale must come out yellow at the pixel that the axes'
    data-to-pixel mapping gives it (within a pixel), and nowhere else in the panel."""
    one = [panel([[0.5, 0.3, 0.0]], [99.0])]
    fig = map_canvas(one, columns=1)
    out = tmp_path / "map.png"
    fig.savefig(out, dpi=DPI)
    image = np.asarray(Image.open(out).convert("RGB")).astype(int)
    width, height = figure_size(one, 1)
    assert image.shape == (round(height * DPI), round(width * DPI), 3)
    ax = fig.axes[0]
    x, y = ax.transData.transform((0.5, 0.3))
    column, row = x, image.shape[0] - y
    yellow = (np.array(colormaps["viridis"](1.0)[:3]) * 255).round()
    box = ax.get_window_extent()
    inside = image[image.shape[0] - int(box.y1):image.shape[0] - int(box.y0), int(box.x0):int(box.x1)]
    hits = np.argwhere((np.abs(inside - yellow) <= 3).all(axis=2)) + [image.shape[0] - int(box.y1), int(box.x0)]
    assert len(hits) >= 1
    assert np.abs(hits - [row, column]).max() <= 1.5, (hits, row, column)


def test_map_figure_writes_the_png_of_its_canvas(tmp_path):
    out = tmp_path / "map.png"
    one = [panel([[0.5, 0.3, 0.0]], [5.0])]
    map_figure(one, out, columns=1)
    assert Image.open(out).size == tuple(round(inches * DPI) for inches in figure_size(one, 1))


def test_empty_map_writes_a_png(tmp_path):
    out = tmp_path / "map.png"
    empty = [panel(np.zeros((0, 3)), np.zeros(0))]
    map_figure(empty, out, columns=1)
    assert Image.open(out).size == tuple(round(inches * DPI) for inches in figure_size(empty, 1))
    assert np.isinf(worst_error_grid(np.zeros((0, 2)), np.zeros(0), (0, 1, 0, 1), 4, 3)).all()


def test_nan_points_are_left_out_and_the_label_says_how_many():
    pts = np.array([[0.2, 0.1, 0.0], [np.nan, 0.1, 0.0], [0.3, 0.2, 0.0], [0.4, 0.2, 0.0]])
    fig = map_canvas([panel(pts, [1.0, 2.0, np.nan, 3.0])], columns=1)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "x (m); 2 of 4 map points not drawn (no finite x, y or error)"
    image = np.asarray(ax.get_images()[0].get_array())
    assert image.dtype == np.uint8   # colours, not a float grid a NaN could reach
    assert (image[..., 3] > 0).sum() == 2


def test_leaderboard_grid_of_panels_has_its_size(tmp_path):
    out = tmp_path / "lb.png"
    rng = np.random.default_rng(0)
    panels = [panel(rng.uniform(0, 3, (10_000, 3)), rng.uniform(0, 40, 10_000), f"method {k}") for k in range(6)]
    map_figure(panels, out, columns=4)
    assert row_heights(panels, 4) == [MAX_AXES, MAX_AXES]   # 3 m square maps: as tall as a row gets
    assert Image.open(out).size == tuple(round(inches * DPI) for inches in figure_size(panels, 4))


def test_a_wide_scene_gets_a_short_row_and_a_tall_one_a_tall_row():
    """A row is as tall as its tallest panel needs at its aspect: an 8 m by 3.6 m scene (as bays) gets
    a short row instead of a square one left half white, a tall scene (crates) the tallest row."""
    wide = panel([[1.0, -1.8, 0.0], [8.0, 1.8, 0.0]], [1.0, 2.0])
    tall = panel([[1.0, -1.5, 0.0], [3.0, 2.0, 0.0]], [1.0, 2.0])
    x0, x1, y0, y1 = view_limits(wide["positions"], wide["p_true"], wide["p_est"])
    short, = row_heights([wide], 1)
    assert MIN_AXES < short < 1.5 and short == pytest.approx(3.0 * (y1 - y0) / (x1 - x0))
    assert row_heights([wide, tall], 1) == [short, MAX_AXES]
    assert row_heights([wide, tall], 2) == [MAX_AXES]   # one row: its tallest panel's height
    assert figure_size([wide], 1)[1] < figure_size([tall], 1)[1]


@pytest.mark.parametrize("enabled", [True, False])
def test_the_garbage_collector_is_left_as_it_was(tmp_path, enabled):
    """The picture pauses the collector (a full collection cost 70-90 ms of it) and restores it."""
    was = gc.isenabled()
    (gc.enable if enabled else gc.disable)()
    try:
        map_figure([panel([[0.5, 0.3, 0.0]], [5.0])], tmp_path / "map.png", columns=1)
        assert gc.isenabled() == enabled
        with pytest.raises(ValueError):   # and after a failed picture too
            map_figure([panel([[0.5, 0.3, 0.0]], [5.0])], tmp_path / "map.png", columns=-1)
        assert gc.isenabled() == enabled
    finally:
        (gc.enable if was else gc.disable)()


def test_no_panel_at_all_is_a_picture_that_says_so(tmp_path):
    """A leaderboard whose runs all failed before their maps has no panel: the old grid divided by
    zero and the leaderboard's files were not written."""
    fig = map_canvas([], columns=4)
    assert [t.get_text() for t in fig.texts] == ["no run produced a map"]
    map_figure([], tmp_path / "lb.png", columns=4)
    assert Image.open(tmp_path / "lb.png").size == (round(4.2 * DPI), round(3.8 * DPI))
    assert figure_size([], 4) == (4.2, 3.8)


def test_frames_whose_icp_failed_are_marked_on_the_estimate_and_in_the_legend():
    failed = np.zeros(20, bool)
    failed[[4, 5, 11]] = True
    lost = panel([[0.2, 0.1, 0.0]], [1.0]) | {"failed": failed}
    fig = map_canvas([panel([[0.2, 0.1, 0.0]], [1.0], "kdtree"), lost], columns=2)
    marks = [line for line in fig.axes[1].get_lines() if line.get_label() == FAILED_LABEL]
    assert len(marks) == 1 and np.allclose(marks[0].get_xydata(), lost["p_est"][failed, :2])
    assert fig.axes[1].get_xlabel().replace("\n", " ").endswith("ICP failed in 3 of 19 tracked frames (pose held)")
    assert not [line for line in fig.axes[0].get_lines() if line.get_label() == FAILED_LABEL]
    legend = [t.get_text() for t in fig.legends[0].get_texts()]   # the second panel's marker, in the one legend
    assert legend == ["true path", "estimate", FAILED_LABEL]


def test_frames_whose_method_raised_are_their_own_mark_not_icp_failures():
    """A frame whose method call raised is held as a failed ICP frame is (``icp_failed``), but the
    picture says which it was: an orange plus and its own count, not a red cross."""
    frames = pd.DataFrame({"icp_failed": [False, True, True, True, False],
                           "icp_reason": ["converged", "lost direction", METHOD_FAILED, METHOD_FAILED, "converged"]})
    flags = failure_flags(frames)
    assert flags["raised"].tolist() == [False, False, True, True, False]
    path = PATH[:5]
    run = panel([[0.2, 0.1, 0.0]], [1.0]) | {"p_true": path, "p_est": path + 0.01, **flags}
    fig = map_canvas([run], columns=1)
    lines = {line.get_label(): line for line in fig.axes[0].get_lines()}
    assert np.allclose(lines[RAISED_LABEL].get_xydata(), run["p_est"][[2, 3], :2])
    assert np.allclose(lines[FAILED_LABEL].get_xydata(), run["p_est"][[1], :2])
    assert fig.axes[0].get_xlabel().replace("\n", " ").endswith(
        "; ICP failed in 1 of 4 tracked frames (pose held); the method failed in 2 of 4 (raised or hung; pose held)")
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["true path", "estimate", FAILED_LABEL, RAISED_LABEL]


@pytest.mark.parametrize("span", [(3.0, 3.0), (9.0, 3.6)])
def test_a_single_run_with_every_mark_keeps_its_legend_and_x_label_inside_the_picture(span):
    """A run's ``map.png`` is one 4.2 in panel: with both marks and points not drawn (counts in the
    thousands), the legend's four entries and the x label's three notes (wrapped) stay inside it,
    above the colour bar, on a square and a wide scene. The first version's one-row legend and
    one-line label ran past both edges."""
    rng = np.random.default_rng(0)
    positions = rng.uniform(0, 1, (12_345, 3)) * [*span, 0.0]
    positions[:1_234, 0] = np.nan
    path = np.column_stack([np.linspace(0.0, 1.0, 1_000), np.zeros(1_000), np.zeros(1_000)])
    failed, raised = np.zeros(1_000, bool), np.zeros(1_000, bool)
    failed[100:400], raised[500:700] = True, True
    run = panel(positions, rng.uniform(0, 40, len(positions)),
                "flaky_dense:Flaky on crates: model tracking, trajectory circle, 1000 frames, seed 0")
    fig = map_canvas([run | {"p_true": path, "p_est": path, "failed": failed | raised, "raised": raised}], columns=1)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer, width = FigureCanvasAgg(fig).get_renderer(), fig.bbox.width
    fig.draw(renderer)
    assert fig.axes[0].get_xlabel().count("\n") == 2
    for artist in (fig.legends[0], fig.axes[0].xaxis.label):
        box = artist.get_window_extent(renderer)
        assert 0 <= box.x0 and box.x1 <= width, f"{artist} spans {box.x0:.0f}-{box.x1:.0f} px of {width:.0f}"
    bar = fig.axes[1]
    assert fig.axes[0].xaxis.label.get_window_extent(renderer).y0 > bar.get_window_extent(renderer).y1
    assert bar.xaxis.label.get_window_extent(renderer).y0 >= 0   # the colour bar's label not cut at the bottom


def test_a_failed_mask_that_does_not_fit_the_poses_is_refused():
    with pytest.raises(ValueError, match="one flag per pose"):
        map_canvas([panel([[0.2, 0.1, 0.0]], [1.0]) | {"failed": np.zeros(3, bool)}])
