"""``assocbench export --drive``: a closed-loop suite's problems as its own loop makes them, driven
by the truth or by one of its methods, frame for frame the loop the leaderboard runs; bad drives."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml
from cli_errors import assert_one_line_error

from assocbench.cli.main import main
from assocbench.dataset import read_card, read_problems
from assocbench.harness.loop import loop_records
from assocbench.harness.suite import load_suite
from assocbench.scoring.metrics import score_frame

pytest.importorskip("pyarrow")

FRAMES = 30
SUITE = {"base": {"loop": True, "frames": FRAMES,
                  "estimator": {"mode": "slam", "target_paired": 1000, "max_new_per_frame": 20, "max_landmarks": 500,
                                "new_landmark_gate": 4, "odometry_sigma_translation": 0.03,
                                "odometry_sigma_rotation": 1.0}},
         "scenes": ["park"], "difficulties": {"hard": {"belief": {"clutter": 2}}},
         "methods": ["mnn", {"name": "loose", "method": "naive", "params": {"threshold": 16}}], "seeds": [3]}


@pytest.fixture(scope="module")
def suite_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("suite") / "planar_loop.yaml"
    path.write_text(yaml.safe_dump(SUITE))
    return path


def leaderboard_loop(suite_file, method: str, params: dict) -> pd.DataFrame:
    """The per-frame records of the leaderboard's own closed loop of ``method`` on the suite's run."""
    spec = load_suite(suite_file).runs[0].spec
    return pd.DataFrame(list(loop_records(spec.source, spec.with_method(method, params))))


def exported(suite_file, tmp_path, drive: str) -> list:
    """The export driven by ``drive``, written twice: the same bytes (a deterministic driver)."""
    for again in ("a", "b"):
        out = tmp_path / f"{drive}-{again}"
        assert main(["export", "--suite", str(suite_file), "--drive", drive, "--out", str(out), "--quiet"]) == 0
    for name in ("problems.parquet", "card.yaml"):
        assert (tmp_path / f"{drive}-a" / name).read_bytes() == (out / name).read_bytes()
    assert read_card(out)["drive"] == drive
    return [item for batch in read_problems(out) for item in batch]


@pytest.mark.parametrize("drive, method, params", [("oracle", "oracle", {}), ("loose", "naive", {"threshold": 16})])
def test_a_driven_export_is_the_leaderboards_own_loop_frame_for_frame(suite_file, tmp_path, capsys, drive, method,
                                                                       params):
    """Each exported problem is the one the leaderboard's loop of that driver met: the same sizes,
    and the driver's answer on it scores exactly as the loop recorded (its truth included)."""
    items = exported(suite_file, tmp_path, drive)
    # the closing line says what made the problems: the driven loop, not a sampled belief
    assert f"the closed loop driven by {drive} included" in capsys.readouterr().out
    frames = leaderboard_loop(suite_file, method, params)
    assert len(items) == len(frames) == FRAMES
    assert [(i.problem.n, i.problem.m) for i in items] == list(zip(frames["n"], frames["m"]))
    for item, (_, row) in zip(items, frames.iterrows()):
        scored = score_frame(item.problem, item.truth, np.asarray(row["association"], dtype=np.int64))
        assert (scored["tp"], scored["fp"], scored["fn"]) == (row["tp"], row["fp"], row["fn"])
    if drive == "loose":   # a sloppy driver's loop is not the truth's: its map, hence its problems, differ
        truth_driven = leaderboard_loop(suite_file, "oracle", {})
        assert list(truth_driven["n"]) != list(frames["n"])


def test_the_open_export_of_a_loop_suite_is_not_its_loop(suite_file, tmp_path, capsys):
    """Without --drive a loop suite is exported open loop (the card says so): the map is the
    scene's, not one built from an empty map."""
    out = tmp_path / "open"
    assert main(["export", "--suite", str(suite_file), "--out", str(out), "--quiet"]) == 0
    assert "rendering and belief sampling included" in capsys.readouterr().out
    card = read_card(out)
    assert card["drive"] == "open" and card["loop_suite_exported_open_loop"] is True
    first = next(iter(read_problems(out)))[0]
    assert first.problem.n > 0 and leaderboard_loop(suite_file, "oracle", {})["n"].iloc[0] == 0


def test_bad_drives_are_one_line_errors(suite_file, tmp_path, capsys):
    assert_one_line_error(capsys, main(["export", "--suite", str(suite_file), "--drive", "jcbb",
                                        "--out", str(tmp_path / "a")]), "neither open, oracle nor a method", "mnn, loose")
    assert_one_line_error(capsys, main(["export", "--suite", "ci", "--drive", "oracle", "--out", str(tmp_path / "b")]),
                          "needs a closed-loop suite")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
