"""Pictures people can read, and `frame` / `render` input handling (issue 10 items 6, 7, 12;
issue 11 item 11): one line instead of a traceback, the file format the name asks for, a
method's bad answers shown as failures, legible titles and marks, a key, ordered and readable
leaderboard plots."""

from __future__ import annotations

import ctypes.util
import os
import subprocess
import sys

import cv2
import numpy as np
import pandas as pd
import pytest

from assocbench.association.problem import Problem
from assocbench.cli.main import main
from assocbench.harness.leaderboard import write_leaderboard
from assocbench.tracks.camera.truth_frame import TruthFrame, draw_truth_frame
from assocbench.tracks.registry import get_track
from assocbench.viz import draw
from assocbench.viz.overlay import draw_association

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the repository
SMALL = ["--resolution", "64x48"]


def one_line_error(capsys, code: int, *needles: str) -> str:
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("assocbench: error:") and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def colour_count(img: np.ndarray, rgb, tol: int = 40) -> int:
    return int(np.sum(np.all(np.abs(img.astype(int) - np.array(rgb)) <= tol, axis=2)))


# -- issue 10.6: one line, not a traceback ---------------------------------------------------------
@pytest.mark.parametrize("res", ["0x0", "640x0", "0x480"])
def test_frame_refuses_a_resolution_without_pixels(capsys, tmp_path, res):
    one_line_error(capsys, main(["frame", "--resolution", res, "-o", str(tmp_path / "f.png")]),
                   "--resolution", "at least 16")


@pytest.mark.parametrize("fps,suffix", [("0", ".gif"), ("-5", ".gif"), ("nan", ".gif"), ("1e9", ".gif"),
                                        ("0", ".mp4")])
def test_render_refuses_a_frame_rate_outside_0_to_100(capsys, tmp_path, fps, suffix):
    out = tmp_path / f"v{suffix}"
    one_line_error(capsys, main(["render", "--fps", fps, "--frames", "2", "-o", str(out), "--quiet"]),
                   "--fps", "(0, 100]")
    assert not out.exists()


@pytest.mark.parametrize("command", [["frame", *SMALL], ["render", "--frames", "2", "--quiet"]])
def test_an_output_name_that_is_a_folder_is_refused(capsys, tmp_path, command):
    folder = tmp_path / ("out.gif" if command[0] == "render" else "out.png")
    folder.mkdir()
    one_line_error(capsys, main([*command, "-o", str(folder)]), "is a folder")
    assert folder.is_dir() and not any(folder.iterdir())


def run_cli(*args: str, **env: str) -> subprocess.CompletedProcess:
    environ = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    return subprocess.run([sys.executable, "-m", "assocbench.cli.main", *args], capture_output=True, text=True,
                          env={**environ, "PYTHONPATH": ROOT, **env})


@pytest.mark.parametrize("backend", [
    "bogus", "glfw",
    pytest.param("osmesa", marks=pytest.mark.skipif(bool(ctypes.util.find_library("OSMesa")),
                                                    reason="libOSMesa is installed: osmesa may work here")),
])
def test_a_gl_backend_that_cannot_render_is_one_line_naming_egl(tmp_path, backend):
    """A bogus name and osmesa fail when mujoco is imported, glfw (no display) when the context
    is made: each is one line that names MUJOCO_GL and how to check EGL."""
    out = tmp_path / "f.png"
    proc = run_cli("frame", *SMALL, "-o", str(out), MUJOCO_GL=backend)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert f"MUJOCO_GL={backend}" in proc.stderr and "MUJOCO_GL=egl" in proc.stderr, proc.stderr
    assert not out.exists()


def test_commands_that_render_nothing_work_with_a_broken_gl_backend():
    proc = run_cli("list", MUJOCO_GL="bogus")
    assert proc.returncode == 0 and "room" in proc.stdout, proc.stderr


# -- issue 10.7: say what is wrong with a scene, write the format asked for -------------------------
def test_a_scene_that_is_not_mjcf_is_not_reported_missing(capsys, tmp_path):
    picture = tmp_path / "board.png"
    picture.write_bytes(b"\x89PNG\r\n\x1a\n")
    err = one_line_error(capsys, main(["frame", "--scene", str(picture), *SMALL]), "not an MJCF file", ".xml")
    assert "not found" not in err
    one_line_error(capsys, main(["frame", "--scene", str(tmp_path), *SMALL]), "is a folder")


@pytest.mark.parametrize("text,needles", [
    # unclosed tag: MuJoCo's first line alone was "XML parse error 6:"
    ('<mujoco>\n<worldbody>\n<geom size="1"/>\n<site name="lm0" pos="0 0 1"\n</worldbody>\n</mujoco>\n',
     ["XML_ERROR_PARSING_ELEMENT", "line 5"]),
    # an unknown attribute: the element and its line were on MuJoCo's second line
    ('<mujoco>\n<worldbody>\n<geom size="1" typo="3"/>\n<site name="lm0"/>\n</worldbody>\n</mujoco>\n',
     ["typo", "line 3"]),
])
def test_mjcf_errors_give_the_line_and_the_reason(capsys, tmp_path, text, needles):
    scene = tmp_path / "bad.xml"
    scene.write_text(text)
    one_line_error(capsys, main(["frame", "--scene", str(scene), *SMALL, "-o", str(tmp_path / "f.png")]), *needles)


@pytest.mark.parametrize("suffix,magic", [(".jpg", b"\xff\xd8\xff"), (".bmp", b"BM")])
def test_frame_writes_the_format_its_extension_names(capsys, tmp_path, suffix, magic):
    out = tmp_path / f"f{suffix}"
    assert main(["frame", *SMALL, "-o", str(out)]) == 0
    assert out.read_bytes()[: len(magic)] == magic
    assert cv2.imread(str(out)).shape == (48, 64, 3)


@pytest.mark.parametrize("name", ["f.xyz", "frame"])
def test_frame_refuses_a_name_it_cannot_write(capsys, tmp_path, name):
    one_line_error(capsys, main(["frame", *SMALL, "-o", str(tmp_path / name)]), name, ".png", ".jpg")
    assert not (tmp_path / name).exists()


# -- issue 11.11: render validates the method's answers as run does ---------------------------------
PLUGINS = '''
import sys
from dataclasses import dataclass
import numpy as np
from assocbench import Associator

@dataclass
class Raises(Associator):
    name = "raises"
    def associate(self, problem):
        raise RuntimeError("boom")

@dataclass
class OutOfRange(Associator):
    name = "out-of-range"
    def associate(self, problem):
        return np.full(problem.n, problem.m + 5)

@dataclass
class Fractional(Associator):
    name = "fractional"
    def associate(self, problem):
        return np.full(problem.n, 0.5)

@dataclass
class Twice(Associator):
    name = "twice"
    def associate(self, problem):
        out = np.full(problem.n, -1)
        out[:2] = 0
        return out

@dataclass
class Exits(Associator):
    name = "exits"
    def associate(self, problem):
        sys.exit(0)
'''


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    (tmp_path / "pictures_plugins.py").write_text(PLUGINS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "pictures_plugins", raising=False)
    yield "pictures_plugins"
    sys.modules.pop("pictures_plugins", None)


@pytest.mark.parametrize("cls,reason", [("Raises", "boom"), ("OutOfRange", "outside"), ("Fractional", "integer"),
                                        ("Twice", "more than once"), ("Exits", "SystemExit")])
def test_render_shows_a_failing_method_as_failed(capsys, tmp_path, plugins, cls, reason):
    """Every frame is drawn with nothing associated and a red 'failed' note, the video is still
    written, and one stderr line counts the failures: exit 1, never a clean 0."""
    from PIL import Image

    out = tmp_path / "run.gif"
    code = main(["render", "--method", f"{plugins}:{cls}", "--frames", "2", "--set", "resolution=[160,120]",
                 "-o", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert code == 1
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err, captured.err
    assert "failed on 2 of 2 frames" in captured.err and reason in captured.err, captured.err
    with Image.open(out) as im:
        assert im.n_frames == 2
        top = np.asarray(im.convert("RGB"))[:40]
    red = (top[..., 0] > 110) & (top[..., 1] < 70) & (top[..., 2] < 70)
    assert red.sum() > 100   # the note's red box under the title


# -- issue 10.12: pictures -----------------------------------------------------------------------
def checkerboard(h=480, w=640, square=3) -> np.ndarray:
    yy, xx = np.mgrid[:h, :w]
    value = np.where(((yy // square) + (xx // square)) % 2 == 0, 235, 20).astype(np.uint8)
    return np.repeat(value[..., None], 3, axis=2)


def test_a_title_is_legible_over_a_checkerboard():
    """Between the letters there is only a dark box, never the board's white squares."""
    text = "checkerboard line frame 200"
    on_black = np.zeros((480, 640, 3), np.uint8)
    draw.label(on_black, text)
    letters = on_black[..., 0] > 60          # strokes and their anti-aliased edges
    ys, xs = np.nonzero(letters)
    on_board = checkerboard()
    draw.label(on_board, text)
    near = cv2.dilate(letters.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    box = np.zeros_like(letters)
    box[ys.min() - 2: ys.max() + 3, xs.min() - 2: xs.max() + 3] = True
    between = box & ~near
    assert np.mean(on_board[between][:, 0] > 150) < 0.02     # was 47 % with outlined text
    assert np.all(on_board[on_black[..., 0] > 200][:, 0] > 200)


def test_hidden_landmark_marks_stand_out_on_any_wall():
    """The gray x vanished on the corridor's grey walls; the mark must show on grey, white and black."""
    for background in (150, 235, 30):
        rgb = np.full((240, 320, 3), background, np.uint8)
        tf = TruthFrame(rgb, projections=np.array([[100.0, 100.0]]), visible=np.array([False]),
                        in_view=np.array([True]), features=np.zeros((0, 2)), labels=np.zeros(0, int))
        patch = draw_truth_frame(tf)[94:107, 94:107].astype(int)
        assert np.sum(np.abs(patch - background).max(axis=2) > 100) >= 15, background


def test_frames_and_overlays_carry_a_key():
    grey = np.full((480, 640, 3), 128, np.uint8)
    tf = TruthFrame(grey, projections=np.zeros((0, 2)), visible=np.zeros(0, bool), in_view=np.zeros(0, bool),
                    features=np.zeros((0, 2)), labels=np.zeros(0, int))
    key = draw_truth_frame(tf)    # no landmark and no feature: every coloured mark is the key's
    for colour in (draw.GREEN, draw.MAGENTA, draw.YELLOW):
        assert colour_count(key, colour) > 5, colour
    empty = Problem(z=np.zeros((0, 2)), R=np.zeros((0, 2, 2)), zhat=np.zeros((0, 2)), P=np.zeros((0, 0)), volume=1.0)
    key = draw_association(grey, empty, np.zeros(0, int))
    for colour in (draw.BLUE, draw.RED, draw.GREEN):
        assert colour_count(key, colour) > 5, colour
    tiny = np.full((48, 64, 3), 128, np.uint8)   # no room for a key: the picture is left alone
    assert np.array_equal(draw_association(tiny, empty, np.zeros(0, int)), tiny)


def summaries(difficulties=("hard", "easy", "medium")) -> pd.DataFrame:
    rows = []
    for scene in ("room", "checkerboard"):
        for d in difficulties:
            for method, (p, r) in {"jcbb": (0.98, 0.97), "mnn": (0.95, 0.96), "lsa": (0.95, 0.96)}.items():
                for seed in (0, 1):
                    rows.append({"scenario": f"{scene}/{d}", "scene": scene, "difficulty": d, "method": method,
                                 "seed": seed, "status": "ok", "precision": p, "recall": r, "f1": 2 * p * r / (p + r),
                                 "perfect": 0.5, "surprisal_gap": 1.0, "runtime_median_ms": 0.2, "frames": 10,
                                 "failures": 0, "timed_out": 0})
    return pd.DataFrame(rows)


def frames_for_runtime() -> pd.DataFrame:
    n = np.r_[np.repeat(np.arange(10, 15), 6), np.repeat(np.arange(50, 55), 6)]
    return pd.DataFrame({"method": "jcbb", "n": n, "runtime_s": 1e-4 * n})


def test_leaderboard_orders_difficulties_easy_medium_hard_then_the_suites(tmp_path):
    paths = write_leaderboard(summaries(("warmup", "hard", "easy", "extreme", "medium")), frames_for_runtime(),
                              tmp_path, get_track("camera"))
    headings = [line[3:] for line in paths["md"].read_text().splitlines() if line.startswith("## ")]
    order = ["easy", "medium", "hard", "warmup", "extreme"]
    assert headings == [f"{s}/{d}" for s in ("checkerboard", "room") for d in order]
    assert list(dict.fromkeys(pd.read_csv(paths["csv"])["scenario"])) == headings


def test_precision_recall_plot_shows_every_method(tmp_path):
    """Difficulty columns easy to hard; axes zoomed to the points; two methods on one spot both
    visible (different colour, shape and size) and named as a tie."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import to_rgb

    from assocbench.scoring.aggregate import leaderboard_table
    from assocbench.viz.plots import method_styles, pr_figure

    table = leaderboard_table(summaries())
    fig = pr_figure(table, ["checkerboard", "room"], ["easy", "medium", "hard"])
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in panels[:3]] == ["checkerboard/easy", "checkerboard/medium", "checkerboard/hard"]
    ax = panels[0]
    assert np.ptp(ax.get_xlim()) <= 0.2 and np.ptp(ax.get_ylim()) <= 0.2
    assert any(t.get_text() == "lsa = mnn" for t in ax.texts)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    img = np.asarray(canvas.buffer_rgba())[..., :3]
    x, y = ax.transData.transform((0.96, 0.95))
    row, col = int(round(img.shape[0] - y)), int(round(x))
    window = img[row - 15: row + 16, col - 15: col + 16]
    styles = method_styles(table["method"])
    assert styles["lsa"]["marker"] != styles["mnn"]["marker"] and styles["lsa"]["ms"] != styles["mnn"]["ms"]
    for method in ("lsa", "mnn"):
        rgb = np.rint(255 * np.array(to_rgb(styles[method]["color"]))).astype(int)
        assert colour_count(window, rgb, 60) > 3, method


def test_runtime_plot_shows_frames_and_breaks_between_clusters_of_n():
    from assocbench.viz.plots import runtime_figure

    frames = frames_for_runtime()
    fig = runtime_figure(frames)
    lines = fig.axes[0].get_lines()
    dots = [ln for ln in lines if ln.get_linestyle() == "None"]
    assert len(dots) == 1 and len(dots[0].get_xdata()) == len(frames)     # every frame is a dot
    median = next(ln for ln in lines if ln.get_label() == "jcbb")
    x, y = np.asarray(median.get_xdata(), float), np.asarray(median.get_ydata(), float)
    finite = np.flatnonzero(np.isfinite(y))
    joined = [(x[a], x[b]) for a, b in zip(finite, finite[1:]) if b == a + 1]
    assert not any(lo < 20 and hi > 45 for lo, hi in joined)   # no segment spans n = 20..45
    assert np.isfinite(y[x < 20]).any() and np.isfinite(y[x > 45]).any()


PLUGINS_THAT_DIE = '''
import ctypes, time
from dataclasses import dataclass
from assocbench import Associator

@dataclass
class Segv(Associator):
    def associate(self, problem):
        if problem.n > 3:
            ctypes.string_at(0)
        return self.empty(problem)

@dataclass
class Sleeper(Associator):
    def associate(self, problem):
        if problem.n > 3:
            time.sleep(60)
        return self.empty(problem)
'''


@pytest.mark.slow   # render isolates as run does: test_faults_plugins' dying and hanging methods, by default
@pytest.mark.parametrize("method,why,limit", [("Segv", "WorkerDied", 30), ("Sleeper", "TimeLimit", 1)])
def test_render_isolates_a_method_that_dies_or_hangs(tmp_path, method, why, limit):
    """render runs the method as run does: a segfault or a hang fails frames, the video is written.
    The segfault gets a long time limit: on a loaded machine a 1 s limit could kill the worker
    before it crashed (seen with two test suites at once on 2 cores: TimeLimit, not WorkerDied)."""
    (tmp_path / "dieplug.py").write_text(PLUGINS_THAT_DIE)
    out = tmp_path / "r.gif"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-m", "assocbench.cli.main", "render", "--method", f"dieplug:{method}",
                           "--frames", "2", "--set", f"time_limit_s={limit}", "--set", "resolution=[320, 240]", "-o", str(out),
                           "--quiet"], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 1 and why in proc.stderr and "Traceback" not in proc.stderr
    assert out.stat().st_size > 0 and not [p for p in tmp_path.iterdir() if p.name.startswith(".r")]


@pytest.mark.parametrize("command", [["frame", "--resolution", "320x240"], ["render", "--frames", "2"]])
def test_an_unwritable_output_file_names_the_o_option(capsys, tmp_path, command):
    blocker = tmp_path / "f.jpg"
    blocker.write_text("a file, not a folder")
    name = "x.png" if command[0] == "frame" else "x.gif"
    code = main([*command, "-o", str(blocker / name)])
    err = capsys.readouterr().err
    assert code == 2 and "-o" in err and "--out" not in err and "Traceback" not in err
