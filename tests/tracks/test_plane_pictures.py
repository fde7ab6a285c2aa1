"""``assocbench frame`` and ``render`` on the lidar tracks (``tracks.plane_pictures``): a top view
per frame of the expected size, with the map, the scan and each feature in its decision's colour;
the dense track's refusal says where its pictures are."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from assocbench.cli.main import main
from assocbench.harness.config import load_run_config, run_spec
from assocbench.tracks.capabilities import RunFrame
from assocbench.tracks.plane_pictures import _caption, view_box
from assocbench.tracks.plane_view import DPI, FEATURE_KINDS, WIDTH_IN, figure_size
from assocbench.tracks.registry import get_track

RIGHT_FEATURES_PX = 300   # the key's mark alone is about 60 pixels


def pixels_of(img: np.ndarray, hex_colour: str, tol: int = 12) -> int:
    rgb = np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)])
    return int(np.sum(np.all(np.abs(img.astype(int) - rgb) <= tol, axis=2)))


def read_png(path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"))


def gif_frames(path) -> list[np.ndarray]:
    im = Image.open(path)
    out = []
    for i in range(im.n_frames):
        im.seek(i)
        out.append(np.asarray(im.convert("RGB")))
    return out


@pytest.mark.parametrize("scene, track", [("post_grid", "planar"), ("office", "lines")])
def test_frame_draws_a_top_view_of_the_scan_and_its_truth(tmp_path, capsys, scene, track):
    out = tmp_path / "f.png"
    assert main(["frame", "--scene", scene, "--frames", "6", "--index", "3", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"what the {track} track's lidar saw" in printed and "features" in printed
    img = read_png(out)
    seq = run_spec(load_run_config(None, [], scene=scene, frames=6)).source.sequence
    the_map = get_track(track).picture_map(seq)
    w, h = figure_size(view_box(get_track(track), seq, the_map))
    assert img.shape == (round(h * DPI), round(w * DPI), 3)
    assert pixels_of(img, FEATURE_KINDS["landmark"][1]) > 50   # the key's mark and the features
    assert pixels_of(img, FEATURE_KINDS["spurious"][1]) > 20   # at least the key's mark


def test_frame_index_outside_the_path_is_one_line(tmp_path, capsys):
    assert main(["frame", "--scene", "post_grid", "--frames", "4", "--index", "4", "-o", str(tmp_path / "f.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--index 4 is outside" in err


@pytest.mark.parametrize("scene, extra", [("post_grid", []), ("post_grid", ["--loop"]), ("office", ["--loop"])])
def test_render_draws_every_frame_with_the_decisions_in_colour(tmp_path, capsys, scene, extra):
    out = tmp_path / "r.gif"
    assert main(["render", "--method", "jcbb", "--scene", scene, "--frames", "4", *extra, "-o", str(out),
                 "--quiet"]) == 0
    assert "wrote" in capsys.readouterr().out
    frames = gif_frames(out)
    assert len(frames) == 4 and len({f.shape for f in frames}) == 1 and frames[0].shape[1] == WIDTH_IN * DPI
    last = frames[-1]
    for kind in ("right", "wrong", "missed", "new", "clutter"):   # each key's mark at least
        assert pixels_of(last, FEATURE_KINDS[kind][1]) > 20, kind
    assert pixels_of(last, FEATURE_KINDS["right"][1]) > RIGHT_FEATURES_PX   # features, not the key's mark alone


def test_the_caption_names_scene_method_frame_and_the_loop(tmp_path):
    spec = run_spec(load_run_config(None, ["estimator.mode=slam"], method="jcbb", scene="post_grid", frames=4,
                                    loop=True))
    track = get_track(spec.track)
    record = {"tp": 3, "fp": 1, "fn": 2, "pos_err": 0.05, "rot_err_deg": 0.5}
    rf = RunFrame(2, None, None, np.zeros(0, np.int64), "", record, estimator=object())
    text = _caption(track, spec, rf, 4)
    for needle in ("post_grid", "jcbb", "frame 2 of 4", "closed loop, ekf slam", "3 right, 1 wrong", "5.0 cm"):
        assert needle in text, text
    failed = _caption(track, spec, RunFrame(2, None, None, np.zeros(0), "TimeLimit: too slow", record), 4)
    assert "FAILED: TimeLimit" in failed


def test_render_refuses_a_dense_run_and_says_where_its_pictures_are(tmp_path, capsys):
    assert main(["render", "--method", "projective", "--scene", "bays", "--frames", "3",
                 "-o", str(tmp_path / "d.gif")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "dense" in err and "map.png" in err
    assert not (tmp_path / "d.gif").exists()
