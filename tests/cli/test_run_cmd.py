"""``run``'s TUM files (a frame without a pose, its estimator had failed, has no line in either) and
its stdout in json and csv format (the summary alone)."""

from __future__ import annotations

import io
import json

import numpy as np
import pandas as pd
import pytest

from assocbench.cli.run_cmd import tum_writers


def test_frames_without_a_pose_are_left_out_of_both_tum_files(tmp_path):
    pose = {"x": 1.0, "y": 2.0, "z": 0.0, "qx": 0.0, "qy": 0.0, "qz": 0.0, "qw": 1.0}
    rows = [{"frame": k, **{f"{p}{c}": v for p in ("true_", "est_") for c, v in pose.items()}} for k in range(3)]
    rows.append({"frame": 3, **{f"true_{c}": v for c, v in pose.items()}, **{f"est_{c}": np.nan for c in pose}})
    for path, write in tum_writers(pd.DataFrame(rows), tmp_path).items():
        write(path)
        lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
        assert [float(line.split()[0]) for line in lines] == [0.0, 1.0, 2.0], path.name


@pytest.mark.parametrize("fmt", ["json", "csv"])
def test_stdout_in_json_or_csv_is_the_summary_alone(tmp_path, capsys, fmt):
    """Reproduction: `assocbench run --scene park --loop --format json` of a run whose estimator
    diverged (odometry 20x noisier than reported) printed `note: the estimator diverged ...` after
    the JSON on stdout, so the output was not JSON. The note goes to stderr."""
    from assocbench.cli.main import main

    code = main(["run", "--scene", "park", "--loop", "--method", "mnn", "--frames", "10", "--set",
                 "estimator.odometry_miscalibration=20", "--out", str(tmp_path), "--format", fmt])
    out, err = capsys.readouterr()
    assert code == 0 and "assocbench: note: the estimator diverged at frame" in err and "chaotic" in err
    summary = json.loads(out) if fmt == "json" else pd.read_csv(io.StringIO(out)).to_dict("records")
    assert len(summary) == 1 and summary[0]["diverged_at"] >= 0
