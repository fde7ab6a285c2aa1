"""Is a recorded log's odometry covariance right? Mean NEES of its dead-reckoned increments over
windows of w poses against the reference solution, for the file's covariance and for it scaled by
``log.odometry_scale``, and the scale that would make each window length consistent (mean NEES 3).

The planar_log track's default scale for a shipped dataset is the one that makes 50-pose windows
consistent (50 frames: the harness's gap after which a re-sighting counts as a revisit);
``tracks/planar_log/consistency.py`` holds the math. ``--figure PATH`` draws mean NEES against
the window length for both covariances, with 3 (consistent) marked.
Usage: python benchmarks/planar_log_odometry.py [--scene victoria_park | LOG] [--scale 11] [--figure nees.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded

from assocbench.sources.range_bearing_log import read_log
from assocbench.tracks.planar_log.consistency import POSE_DOF, window_nees
from assocbench.tracks.planar_log.reference import reference_solution
from assocbench.tracks.planar_log.settings import SHIPPED_ODOMETRY_SCALES
from assocbench.tracks.planar_log.track import shipped_log

WINDOWS = (1, 2, 5, 10, 20, 50, 100, 200, 500)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="victoria_park", help="a shipped dataset or a log file")
    p.add_argument("--scale", type=float, default=None, help="the scale to show beside 1 (default: the track's)")
    p.add_argument("--figure", type=Path, default=None, help="write mean NEES against window length here (PNG)")
    args = p.parse_args()
    path = shipped_log(args.scene) if args.scene in SHIPPED_ODOMETRY_SCALES else Path(args.scene)
    scale = args.scale or SHIPPED_ODOMETRY_SCALES.get(args.scene, 1.0)
    log = read_log(path)
    reference = reference_solution(log)
    poses = reference.poses
    print(f"reference solution: {reference.describe()}")
    windows = [w for w in WINDOWS if w < len(poses)]
    means = [float(np.mean(window_nees(log, poses, w))) for w in windows]
    counts = [len(window_nees(log, poses, w)) for w in windows]
    print(f"{log.name}: {len(poses)} poses; mean NEES of w-pose dead reckoning against the reference solution "
          f"(consistent: {POSE_DOF})")
    print_table(["window (poses)", "windows", "NEES, file covariance", f"NEES, x{scale:g}", "consistent scale"],
                [[w, n, f"{m:.2f}", f"{m / scale:.2f}", f"{m / POSE_DOF:.2f}"] for w, n, m in zip(windows, counts, means)])
    if args.figure:
        figure(windows, means, scale, log.name).savefig(args.figure, dpi=110)
        print(f"wrote {args.figure}")


def figure(windows: list[int], means: list[float], scale: float, name: str):
    """Mean NEES against window length (log-log), the file's covariance and the scaled one."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.2, 3.4))
    ax = fig.subplots()
    ax.loglog(windows, means, "o-", label="file covariance")
    ax.loglog(windows, np.array(means) / scale, "s-", label=f"covariance x{scale:g} (log.odometry_scale)")
    ax.axhline(POSE_DOF, color="0.3", ls="--", lw=1, label=f"consistent: {POSE_DOF}")
    ax.axvline(50, color="0.6", ls=":", lw=1)
    ax.set(xlabel="window (poses)", ylabel="mean NEES of dead reckoning", title=f"{name}: odometry against the reference")
    ax.legend(fontsize=7, frameon=False)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    run_recorded(main)
