"""Pictures of the closed loop: the OpenCV top view, ``render --loop`` (overlay beside the top
view, replayed from the recorded associations) and the loop leaderboard's matplotlib figures."""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd
import pytest
from scipy.stats import chi2

from assocbench.cli.main import main
from assocbench.tracks.camera import topview
from assocbench.tracks.camera.topview import top_view
from assocbench.viz.loop_plots import ORACLE_LABEL, ate_figure, map_figure, nees_band, nees_figure
from assocbench.viz.plots import save_figure

BOUNDS = (-2.0, 2.0, -2.0, 2.0)
NO_MAP = (np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0, bool))


def mask(img: np.ndarray, rgb, tol: int = 30) -> np.ndarray:
    return np.all(np.abs(img.astype(int) - np.array(rgb)) <= tol, axis=2)


def path_at(y: float) -> np.ndarray:
    """A straight true path along x from -1 to 1 m at height ``y``."""
    x = np.linspace(-1.0, 1.0, 21)
    return np.column_stack([x, np.full_like(x, y), np.full_like(x, 1.5)])


# -- the top view ------------------------------------------------------------------------------------
@pytest.mark.parametrize("size", [(480, 480), (120, 300), (300, 120)])
def test_top_view_is_an_rgb_image_of_the_requested_size(size):
    img = top_view(path_at(0.0), path_at(0.0), np.eye(3), path_at(1.5), *NO_MAP, size=size, bounds=BOUNDS)
    assert img.shape == (*size, 3) and img.dtype == np.uint8


def test_top_view_draws_the_trajectory_where_it_is_with_y_up():
    """The path from x = -1 to 1 m is drawn as a thin horizontal line starting a quarter of the
    width from the left edge (the world is 4 m wide); a path at y = +1 lies above one at y = -1."""
    h, w = 400, 200   # tall: the width fixes the scale, s = (w - 1) / 4 px per metre
    empty = top_view(np.zeros((0, 3)), np.zeros((0, 3)), None, np.zeros((0, 3)), *NO_MAP, size=(h, w), bounds=BOUNDS)
    rows = {}
    for y in (1.0, -1.0):
        img = top_view(path_at(y), np.zeros((0, 3)), None, np.zeros((0, 3)), *NO_MAP, size=(h, w), bounds=BOUNDS)
        drawn = mask(img, topview.TRUE_COLOR, 60) & ~mask(empty, topview.TRUE_COLOR, 60)
        r, c = np.nonzero(drawn)
        s = (w - 1) / 4.0
        assert len(r) > 50
        assert abs(c.min() - ((w - 1) / 2 - s)) <= 3   # starts at x = -1 m
        middle = np.abs(c - (w - 1) / 2) < s / 2       # away from the camera's ring at x = +1 m
        assert middle.sum() > 20 and r[middle].max() - r[middle].min() <= 5   # a line, not a blob
        rows[y] = r[middle].mean()
    assert rows[1.0] < rows[-1.0]   # z up: larger y is higher in the picture


def test_top_view_ellipse_is_three_sigma_of_the_xy_marginal():
    """A landmark with σ_x = 0.5 m and no y variance (a singular covariance) is drawn as a line
    3σ = 1.5 m to either side of its mean, in the confirmed colour."""
    h, w = 400, 200
    cov = np.diag([0.25, 0.0, 0.0])[None]
    img = top_view(np.zeros((0, 3)), np.zeros((0, 3)), None, np.zeros((0, 3)), np.zeros((1, 3)), cov,
                   np.array([True]), size=(h, w), bounds=BOUNDS)
    r, c = np.nonzero(mask(img, topview.CONFIRMED_COLOR, 60))
    s = (w - 1) / 4.0
    assert abs((c.max() - c.min()) - 2 * 1.5 * s) <= 6
    assert r.max() - r.min() <= 8


def test_top_view_handles_an_empty_map_and_bad_covariances():
    """No landmarks at all; then a zero, an indefinite, a NaN and a huge covariance, a NaN mean and
    an estimate far outside the view: an image of the right size, no exception."""
    img = top_view(path_at(0.0), path_at(0.0), np.eye(3), np.zeros((0, 3)), *NO_MAP, size=(100, 150))
    assert img.shape == (100, 150, 3)
    assert not mask(img, topview.CONFIRMED_COLOR).any() and not mask(img, topview.TENTATIVE_COLOR).any()
    covs = np.stack([np.zeros((3, 3)), np.diag([1.0, -1.0, 0.0]), np.full((3, 3), np.nan), np.eye(3) * 1e12,
                     np.eye(3)])
    means = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [np.nan, 0, 0]], float)
    far = path_at(0.0) + [1e9, 0, 0]
    img = top_view(path_at(0.0), far, np.eye(3), path_at(1.0), means, covs, np.array([1, 0, 1, 0, 1], bool),
                   size=(240, 320), bounds=BOUNDS, true_R=np.eye(3), title="frame 3")
    assert img.shape == (240, 320, 3)


@pytest.mark.parametrize("kwargs,needle", [({"size": (0, 10)}, "size"), ({"bounds": (1.0, 1.0, 0.0, 2.0)}, "bounds"),
                                           ({"confirmed": np.ones(2, bool)}, "2 confirmed flags")])
def test_top_view_refuses_bad_input_in_one_line(kwargs, needle):
    from assocbench.errors import UserError

    args = {"map_means": np.zeros((1, 3)), "map_covs": np.eye(3)[None], "confirmed": np.ones(1, bool)} | kwargs
    with pytest.raises(UserError, match=needle):
        top_view(path_at(0.0), path_at(0.0), None, np.zeros((0, 3)), **args)


def test_view_bounds_hold_every_point_with_a_margin():
    b = topview.view_bounds(path_at(0.0), np.array([[3.0, -4.0, 0.0], [np.nan, 0, 0]]))
    assert b[0] < -1.0 and b[1] > 3.0 and b[2] < -4.0 and b[3] > 0.0
    assert topview.view_bounds(np.zeros((0, 3)))[1] - topview.view_bounds(np.zeros((0, 3)))[0] >= 1.0


# -- render --loop -----------------------------------------------------------------------------------
def gif_frames(path):
    from PIL import Image

    with Image.open(path) as im:
        return im.n_frames, im.size


def test_render_loop_puts_the_top_view_beside_the_camera_frame(capsys, tmp_path):
    """Each frame is the 160x120 overlay with the top view to its right; the replayed filter
    matches the run's estimate (no warning), and the run is clean (exit 0)."""
    out = tmp_path / "x.gif"
    code = main(["render", "--method", "mnn", "--loop", "--frames", "6", "--set", "resolution=[160,120]",
                 "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "warning" not in err, err
    n, (width, height) = gif_frames(out)
    assert n == 6 and height == 120 and width > 160 + 60


FLAKY = '''
from dataclasses import dataclass
import numpy as np
from assocbench import Associator

@dataclass
class EveryOther(Associator):
    """Nearest-free-feature pairs on odd calls, an exception on even ones (warm-up is call 1)."""
    name = "every-other"
    calls: int = 0
    def associate(self, problem):
        self.calls += 1
        if self.calls % 2 == 0:
            raise RuntimeError("even call")
        return np.full(problem.n, -1)
'''


def test_render_loop_replays_failed_frames_as_the_run_did(capsys, tmp_path, monkeypatch):
    """A method failing on some frames: the video is written, exit 1 with one line counting the
    failures, and the replay (failed frames only predict) matches the recorded estimate."""
    (tmp_path / "loop_flaky.py").write_text(FLAKY)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "loop_flaky", raising=False)
    out = tmp_path / "x.gif"
    code = main(["render", "--method", "loop_flaky:EveryOther", "--loop", "--frames", "6",
                 "--set", "resolution=[160,120]", "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 1
    assert "failed on 3 of 6 frames" in err and "warning" not in err, err
    assert gif_frames(out)[0] == 6


# -- the loop leaderboard's figures ------------------------------------------------------------------
METHODS = ("oracle", "jcbb", "mnn")


def test_ate_figure_writes_a_png_with_the_oracle_hatched(tmp_path):
    rows = [{"scenario": sc, "method": m, "ate_rmse": a, "ate_rmse_std": a / 5}
            for sc in ("room/easy", "room/hard", "corridor/hard")
            for m, a in zip(METHODS, (0.02, 0.03, 2.0 if sc == "room/hard" else 0.05))]
    fig = ate_figure(pd.DataFrame(rows))
    ax = fig.axes[0]
    assert ORACLE_LABEL in [t.get_text() for t in ax.get_xticklabels()]
    hatched = [p for p in ax.patches if p.get_hatch()]
    assert len(hatched) == 1 and hatched[0].get_height() == pytest.approx(0.02)
    panels = {a.get_title(): a for a in fig.axes if a.axison}
    assert sorted(panels) == ["corridor/hard", "room/easy", "room/hard"]   # corridor/easy: no panel
    # room/hard spans 100x: every panel on a log axis, so neighbours of one quantity share a scale
    assert {ax.get_yscale() for ax in panels.values()} == {"log"}
    save_figure(fig, tmp_path / "ate.png")
    assert (tmp_path / "ate.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_nees_figure_shades_the_chi2_6_band(tmp_path):
    rng = np.random.default_rng([7, 1])
    rows = [{"scenario": sc, "method": m, "seed": s, "frame": k, "nees": float(rng.chisquare(6)) if k else np.nan}
            for sc in ("room/easy", "room/hard") for m in METHODS for s in range(3) for k in range(12)]
    lo, hi, bound = nees_band()
    assert (lo, hi, bound) == pytest.approx((chi2.ppf(0.025, 6), chi2.ppf(0.975, 6), chi2.ppf(0.999, 6)))
    fig = nees_figure(pd.DataFrame(rows))
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    span = ax.patches[0]   # axhspan: a Polygon or a Rectangle, depending on matplotlib
    ys = span.get_patch_transform().transform(span.get_path().vertices)[:, 1]
    assert (ys.min(), ys.max()) == pytest.approx((lo, hi))
    assert len(ax.lines) == 1 + len(METHODS)   # the dashed bound and a line per method
    save_figure(fig, tmp_path / "nees.png")
    assert (tmp_path / "nees.png").stat().st_size > 1000


@pytest.mark.parametrize("peak", [30.0, 5e4])
def test_every_nees_panel_keeps_labelled_ticks_over_any_range(tmp_path, peak):
    """The committed planar NEES picture had two panels with no y labels at all: a tight prior's
    first-frame NEES of 5e-4 and a diverged method's 5e4 span eight decades, and a 1-2-5 locator
    labels none of its ticks there. Every panel must show at least three labelled ticks."""
    rows = [{"scenario": sc, "method": m, "seed": 0, "frame": k, "nees": 5e-4 if k == 0 else (peak if m == "mnn" else 3.0),
             "nees_dof": 3} for sc in ("park/easy", "park/hard") for m in METHODS for k in range(20)]
    fig = nees_figure(pd.DataFrame(rows))
    fig.canvas.draw()
    for ax in (a for a in fig.axes if a.axison):
        low, high = ax.get_ylim()
        labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text() and low <= t.get_position()[1] <= high]
        assert len(labels) >= 3, (ax.get_title(), labels)
        assert low > 5e-4   # the first frame's 5e-4 is drawn at the floor, which the footnote names


@pytest.mark.parametrize("with_map", [False, True])
def test_map_figure_writes_a_png_with_or_without_the_map(tmp_path, with_map):
    t = np.linspace(0, 2 * np.pi, 20)
    rows = [{"method": m, "frame": k, "true_x": np.cos(a), "true_y": np.sin(a), "est_x": np.cos(a) + 0.01 * k,
             "est_y": np.sin(a)} for m in METHODS for k, a in enumerate(t)]
    landmarks = np.array([[x, y, 1.0] for x in (-3.0, 0.0, 3.0) for y in (-3.0, 3.0)])
    maps = {m: landmarks + 0.05 for m in METHODS} if with_map else None
    fig = map_figure(pd.DataFrame(rows), landmarks, maps, title="room/hard seed 0")
    notes = " ".join(t.get_text() for t in fig.texts)
    assert ("map not recorded" in notes) != with_map
    save_figure(fig, tmp_path / "map.png")
    assert (tmp_path / "map.png").read_bytes()[:4] == b"\x89PNG"
