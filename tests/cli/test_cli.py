"""The command line: bad input is one line on stderr, exit code 2, no traceback; files are atomic."""

from __future__ import annotations

import os
import subprocess
import sys

import pandas as pd
import pytest

from assocbench.cli.main import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the repository


def run_cli(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "assocbench.cli.main", *args], capture_output=True, text=True,
                          cwd=cwd, env={**os.environ, "PYTHONPATH": ROOT})


def assert_one_line_error(capsys, code: int, *needles: str) -> None:
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("assocbench: error:"), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, err


@pytest.mark.parametrize("args,needles", [
    (["frame", "--scene", "missing.xml"], ["missing.xml", "not found"]),
    (["frame", "--resolution", "4000x3000"], ["exceeds the offscreen buffer", "offwidth"]),
    (["frame", "--trajectory", "spiral"], ["unknown trajectory 'spiral'", "circle"]),
    (["frame", "--resolution", "big"], ["WIDTHxHEIGHT"]),
    (["run", "--method", "jcbbb", "--frames", "2"], ["unknown method 'jcbbb'", "did you mean jcbb"]),
    (["run", "--set", "belief.sigma_rot=2", "--frames", "2"], ["unknown key 'belief.sigma_rot'", "sigma_rotation"]),
    (["run", "--set", "frames"], ["key=value"]),
    (["run", "--frames", "0"], ["frames must be an integer >= 1"]),
    (["run", "--set", "belief.map_fraction=2"], ["map_fraction"]),
    (["run", "--set", "msaa=-1"], ["msaa must be null", "0..16"]),
    (["run", "--method", "jcbb", "--set", "params.confidance=0.9", "--frames", "2"], ["confidance", "accepted are"]),
    (["check", "--baseline", "no/such/baseline.csv"], ["baseline", "not found", "--update"]),
    (["leaderboard", "--suite", "no-suite.yaml"], ["no-suite.yaml", "not found"]),
])
def test_bad_input_is_a_one_line_error(capsys, args, needles):
    assert_one_line_error(capsys, main(args), *needles)


@pytest.mark.parametrize("args,needle", [
    (["run", "--frames", "5", "--set", "frames=abc"], "--frames 5 and --set frames=abc disagree: give frames once"),
    (["run", "--loop", "--set", "loop=false"], "--loop and --set loop=false disagree"),
])
def test_a_flag_and_a_set_that_disagree_are_refused(capsys, args, needle):
    """Reproduction: `assocbench run --frames 5 --set frames=abc` ran 5 frames and dropped the --set
    without a word (the flag won, right or wrong); so did `--loop --set loop=false`."""
    assert_one_line_error(capsys, main(args), needle)


@pytest.mark.parametrize("args,needles", [
    (["run", "--bogus"], ["unrecognized arguments: --bogus", "(see assocbench run --help)"]),
    (["run", "--frames", "x"], ["invalid int value", "(see assocbench run --help)"]),
    (["bogus"], ["invalid choice", "(see assocbench --help)"]),
])
def test_argument_errors_point_at_the_right_help(capsys, args, needles):
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert_one_line_error(capsys, exc.value.code, *needles)


@pytest.mark.parametrize("name,text,command,needles", [
    ("empty.xml", "<mujoco><worldbody><geom type='box' size='1 1 1'/></worldbody></mujoco>",
     ["frame", "--scene"], ["has no landmarks", "lm"]),
    ("bad.yaml", "frames: [1, 2\nscene: room\n", ["run", "--config"], ["malformed YAML", "line"]),
    ("cfg.yaml", "scene: room\nbelif: {clutter: 2}\n", ["run", "--config"], ["unknown key 'belif.clutter'", "did you mean 'belief.clutter'"]),
])
def test_bad_input_files(capsys, tmp_path, name, text, command, needles):
    """An MJCF without landmarks, malformed YAML, an unknown key in a YAML config."""
    path = tmp_path / name
    path.write_text(text)
    assert_one_line_error(capsys, main([*command, str(path)]), *needles)


def test_unwritable_output_folder(capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert_one_line_error(capsys, main(["run", "--frames", "2", "--out", str(blocker / "sub")]), "cannot create output folder")


def test_subprocess_exit_code_and_stderr():
    proc = run_cli("run", "--method", "nonsense")
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "Traceback" not in proc.stderr
    assert "unknown method 'nonsense'" in proc.stderr


def test_frame_writes_a_png_and_says_what_it_saw(tmp_path, capsys):
    out = tmp_path / "frame.png"
    assert main(["frame", "--scene", "room", "--index", "20", "-o", str(out)]) == 0
    import cv2

    img = cv2.imread(str(out))
    assert img.shape == (480, 640, 3)
    said = capsys.readouterr().out
    assert "landmarks visible" in said and "labelled" in said


def test_run_twice_gives_identical_csvs_except_timing(tmp_path, capsys):
    outs = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        assert main(["run", "--method", "jcbb", "--frames", "6", "--out", str(out)]) == 0
        outs.append(out)
    for name in ("frames.csv", "summary.csv"):
        a, b = (pd.read_csv(o / name) for o in outs)
        timing = [c for c in a.columns if c.startswith("runtime")]
        assert timing
        pd.testing.assert_frame_equal(a.drop(columns=timing), b.drop(columns=timing))
    assert "precision" in capsys.readouterr().out


def test_the_leaderboard_says_how_many_runs_it_computed_and_how_many_it_reused(tmp_path, capsys):
    """A user adding a method to a suite sees that only its runs ran (and removing one, that none did)."""
    suite, out = tmp_path / "suite.yaml", tmp_path / "board"
    for methods, said in (("[mnn]", "computed 2 runs, reused 0"), ("[mnn, lsa]", "computed 2 runs, reused 2"),
                          ("[lsa]", "computed 0 runs, reused 2")):
        suite.write_text(f"base: {{frames: 2}}\nscenes: [checkerboard]\nmethods: {methods}\nseeds: [0, 1]\n")
        assert main(["leaderboard", "--suite", str(suite), "--out", str(out), "--quiet"]) == 0
        assert f"assocbench: {said} stored in {out / 'runs'}\n" in capsys.readouterr().err


def test_list_names_methods_scenes_and_trajectories(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in ("enn", "mnn", "ml", "snn", "jcbb", "lsa", "room", "checkerboard", "corridor", "figure-eight", "loop"):
        assert f"  {name} " in out


def test_readme_plugin_example_runs_from_the_cli(tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([ROOT, os.path.join(ROOT, "examples")])}
    proc = subprocess.run([sys.executable, "-m", "assocbench.cli.main", "run", "--method", "my_assoc:GatedNearest",
                           "--frames", "3", "--set", "params.confidence=0.9", "--out", str(tmp_path), "--format", "csv"],
                          capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert summary.loc[0, "method"] == "my_assoc:GatedNearest" and summary.loc[0, "frames"] == 3
    assert summary.loc[0, "recall"] > 0.2


@pytest.mark.parametrize("suffix", [".gif", ".mp4"])
def test_render_writes_a_video_of_the_run(tmp_path, suffix):
    out = tmp_path / f"run{suffix}"
    assert main(["render", "--method", "mnn", "--frames", "3", "-o", str(out), "--quiet"]) == 0
    assert out.stat().st_size > 10_000
    if suffix == ".gif":
        from PIL import Image

        with Image.open(out) as im:
            assert im.n_frames == 3 and im.size == (640, 480)
    else:
        import cv2

        cap = cv2.VideoCapture(str(out))
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 3
        cap.release()


def video_codec(path) -> str:
    """The sample entry of an MP4's first track (``avc1``: H.264; ``mp4v``: MPEG-4 Part 2), read
    from its boxes: moov > trak > mdia > minf > stbl > stsd."""
    import struct

    data = path.read_bytes()

    def boxes(start: int, end: int):
        while start + 8 <= end:
            size, kind = struct.unpack(">I4s", data[start:start + 8])
            yield kind.decode("latin-1"), start + 8, start + size
            start += size

    def find(start: int, end: int, path_: list[str]) -> str:
        for kind, body, stop in boxes(start, end):
            if kind == path_[0]:
                if len(path_) == 1:   # stsd: version and flags, entry count, then the first entry
                    return data[body + 12:body + 16].decode("latin-1")
                return find(body, stop, path_[1:])
        return ""
    return find(0, len(data), ["moov", "trak", "mdia", "minf", "stbl", "stsd"])


def test_an_mp4_is_h264_which_browsers_play(tmp_path):
    """Reproduction: `assocbench render -o run.mp4` wrote MPEG-4 Part 2 (OpenCV's mp4v), which
    Chromium and most browsers cannot play. It writes H.264 now (imageio-ffmpeg's encoder)."""
    import subprocess

    ffmpeg = pytest.importorskip("imageio_ffmpeg")
    for scene, out in (("room", tmp_path / "run.mp4"), ("park", tmp_path / "park.mp4")):
        assert main(["render", "--method", "mnn", "--scene", scene, "--frames", "3", "-o", str(out), "--quiet"]) == 0
        assert video_codec(out) == "avc1", video_codec(out)
        probe = subprocess.run([ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(out)], capture_output=True, text=True)
        assert "Video: h264" in probe.stderr and "yuv420p" in probe.stderr, probe.stderr


def test_without_the_video_extra_an_mp4_is_refused_in_one_line_and_a_gif_works(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)   # import imageio_ffmpeg now raises ImportError
    out = tmp_path / "run.mp4"
    assert_one_line_error(capsys, main(["render", "--frames", "2", "-o", str(out), "--quiet"]),
                          "pip install 'assocbench[video]'", "or write a .gif")
    assert not out.exists()
    assert main(["render", "--frames", "2", "-o", str(tmp_path / "run.gif"), "--quiet"]) == 0


def test_render_rejects_an_unknown_video_format(capsys, tmp_path):
    assert_one_line_error(capsys, main(["render", "-o", str(tmp_path / "run.avi")]), ".mp4 or .gif")


def test_list_gives_each_tracks_own_description_of_a_shared_trajectory(capsys):
    """``waypoints`` is a camera's path on one track and a robot's on the lidar tracks: both said."""
    assert main(["list", "trajectories"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("  waypoints "))
    assert "[camera] Through the waypoints" in line and "[planar, lines] the user's own path" in line, line


@pytest.mark.parametrize("command", [["list"], ["list", "methods"]])
def test_output_into_a_reader_that_left_ends_quietly(command):
    """Reproduction: ``assocbench list | true`` (a reader that stops before the output ends, like
    ``| head -1``) printed a ``BrokenPipeError`` traceback and exited 1."""
    child = subprocess.Popen([sys.executable, "-m", "assocbench.cli.main", *command], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    child.stdout.close()   # the reader leaves before the command writes
    err = child.stderr.read()
    assert child.wait(timeout=120) == 141 and err == "", err
