"""The dense leaderboard's Markdown: counts of frames read as counts."""

import pandas as pd

from assocbench.tracks.dense.columns import DENSE_COLUMNS
from assocbench.tracks.dense.leaderboard import dense_markdown, dense_table


def summaries(icp_failures: list[int]) -> pd.DataFrame:
    """One run per seed of projective on crates, every column set, ``icp_failures`` as given."""
    rows = []
    for seed, lost in enumerate(icp_failures):
        row = {c: 1.0 for c in DENSE_COLUMNS} | {"status": "ok", "frames": 40, "failures": 0,
                                                 "icp_failures": lost, "wrong_steps": 0}
        rows.append({"scenario": "crates/default", "method": "projective", "seed": seed} | row)
    return pd.DataFrame(rows)


def row_cells(md: str) -> dict[str, str]:
    header = next(line for line in md.splitlines() if line.startswith("| method"))
    row = next(line for line in md.splitlines() if line.startswith("| projective"))
    return dict(zip(header.split(" | "), row.split(" | ")))


def test_a_count_of_frames_of_one_seed_prints_as_a_whole_number():
    cells = row_cells(dense_markdown(dense_table(summaries([3]))))
    assert cells["ICP failures"] == "3" and cells["wrong steps"] == "0"


def test_a_mean_count_over_seeds_keeps_its_fraction():
    cells = row_cells(dense_markdown(dense_table(summaries([3, 0]))))
    assert cells["ICP failures"] == "1.5" and cells["wrong steps"] == "0"


def test_the_leaderboard_picture_gets_the_frames_whose_icp_failed():
    from assocbench.tracks.dense.leaderboard import pictures

    rows = [{"scenario": "crates/default", "method": "projective", "seed": 0, "frame": k, "icp_failed": k == 2,
             "final_map": "[0.5, 0.5, 0.0, 1.0]" if k == 3 else None}
            | {f"{p}{c}": 0.1 * k for p in ("true_", "est_") for c in "xyz"} for k in range(4)]
    (panel,) = pictures(pd.DataFrame(rows))
    assert panel["failed"].tolist() == [False, False, True, False]


def test_the_leaderboard_keeps_what_tells_a_raising_method_from_icp_failing():
    """The sweep keeps a run's frames for the leaderboard's picture; it must keep ``icp_reason``, or
    a frame whose method raised is drawn and counted as ICP failing (it was dropped)."""
    from assocbench.tracks.dense.leaderboard import pictures
    from assocbench.tracks.dense.summary import METHOD_FAILED
    from assocbench.tracks.registry import get_track

    reasons = ["first frame (given pose)", "no convergence", METHOD_FAILED, "converged"]
    per_frame = pd.DataFrame([{"frame": k, "icp_failed": k in (1, 2), "icp_reason": reasons[k], "error": "",
                               "final_map": "[0.5, 0.5, 0.0, 1.0]" if k == 3 else None}
                              | {f"{p}{c}": 0.1 * k for p in ("true_", "est_") for c in "xyz"} for k in range(4)])
    per_frame.loc[2, "error"] = "RuntimeError: boom"
    label = {"scenario": "crates/default", "scene": "crates", "difficulty": "default", "method": "flaky", "seed": 0}
    kept = ["frame"] + [c for c in get_track("dense").columns(False).frames if c in per_frame]
    (panel,) = pictures(per_frame.assign(**label)[list(label) + kept])
    assert panel["raised"].tolist() == [False, False, True, False]
    assert (panel["failed"] & ~panel["raised"]).tolist() == [False, True, False, False]
