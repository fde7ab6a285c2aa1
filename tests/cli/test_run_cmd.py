"""``run``'s TUM files: a frame without a pose (its estimator had failed) has no line in either."""

from __future__ import annotations

import numpy as np
import pandas as pd

from assocbench.cli.run_cmd import tum_writers


def test_frames_without_a_pose_are_left_out_of_both_tum_files(tmp_path):
    pose = {"x": 1.0, "y": 2.0, "z": 0.0, "qx": 0.0, "qy": 0.0, "qz": 0.0, "qw": 1.0}
    rows = [{"frame": k, **{f"{p}{c}": v for p in ("true_", "est_") for c, v in pose.items()}} for k in range(3)]
    rows.append({"frame": 3, **{f"true_{c}": v for c, v in pose.items()}, **{f"est_{c}": np.nan for c in pose}})
    for path, write in tum_writers(pd.DataFrame(rows), tmp_path).items():
        write(path)
        lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
        assert [float(line.split()[0]) for line in lines] == [0.0, 1.0, 2.0], path.name
