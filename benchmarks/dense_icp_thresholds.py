"""Evidence for ICP's failure thresholds (``IcpConfig``): what the final inlier share, residual
rms and condition number look like when ICP ends at the true pose and when it ends elsewhere.

Synthetic frames (tests/dense_synthetic.py, 320x240): the room corner with a crate and without it
(constrained) and a single wall (degenerate), noise-free and with the sensor's axial noise σ(z) = k (0.0012 +
0.0019 z²) for k = 0.25 and 1 (grazing > 75 deg dropped). The source is the frame at pose A, the
target the frame at B = A moved 2 deg / 5 cm; ICP starts from B perturbed by s deg and s cm
(random axis and direction) for s in SIZES, ``--seeds`` draws each.

A run ends "at truth" when its error is below 1 mm / 0.1 deg (noise-free) or 1 cm / 0.5 deg
(noisy). Columns over the runs that converged (last update below the convergence thresholds):
at truth: count, largest condition, smallest share, largest rms; elsewhere: count, smallest
condition, largest share; then with the default thresholds, the runs accepted elsewhere (must be
0) and the runs at truth rejected.

Usage: python benchmarks/dense_icp_thresholds.py [--seeds 4]   (about 4 min on one core)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from dense_synthetic import (  # noqa: E402  # noqa: E402
    ROOM,
    ROOM_EYE,
    ROOM_TARGET,
    WALL,
    WALL_EYE,
    WALL_TARGET,
    perturb,
    pose_at,
    pose_error,
    render,
    source_set,
)

from assocbench.associators.registry import make_dense_associator  # noqa: E402
from assocbench.tracks.dense.icp import icp  # noqa: E402
from assocbench.tracks.dense.settings import IcpConfig
from assocbench.tracks.dense.warm import warm_dense  # noqa: E402

SIZES = (0, 1, 3, 5, 10, 15, 20, 30, 45)
SCENES = {"room": (ROOM, ROOM_EYE, ROOM_TARGET), "corner": (ROOM[:3], ROOM_EYE, ROOM_TARGET),
          "wall": (WALL, WALL_EYE, WALL_TARGET)}


def frames(scene: str, k: float):
    """Source frame at A, target frame at B (A moved 2 deg / 5 cm), noise scale k."""
    boxes, eye, target = SCENES[scene]
    noise = dict(sigma_base=0.0012 * k, sigma_quad=0.0019 * k, grazing_deg=75.0) if k else {}
    RA, tA = pose_at(eye, target)
    RB, tB = perturb(RA, tA, 2.0, 0.05, np.random.default_rng(7))
    return render(boxes, RA, tA, rng=np.random.default_rng([1]), **noise), render(
        boxes, RB, tB, rng=np.random.default_rng([2]), **noise)


def runs(scene: str, k: float, method: str, seeds: int) -> list[tuple]:
    """(at_truth, converged, failed, share, rms, condition) per start."""
    A, B = frames(scene, k)
    pts, nrm, *_ = source_set(A)
    associator, cfg = make_dense_associator(method), IcpConfig()
    tol_m, tol_deg = (0.001, 0.1) if k == 0 else (0.01, 0.5)
    out = []
    for size in SIZES:
        for seed in range(seeds):
            R0, t0 = perturb(B.R, B.t, size, size / 100, np.random.default_rng([seed, size]))
            r = icp(pts, nrm, B, associator, R0, t0, cfg)
            em, ed = pose_error(r.R, r.t, B.R, B.t)
            out.append((em < tol_m and ed < tol_deg, r.converged, r.failed, r.inlier_share, r.rms, r.condition))
    return out


def row(label: list, res: list[tuple]) -> list:
    good = [r for r in res if r[0] and r[1]]
    wrong = [r for r in res if not r[0] and r[1]]

    def agg(rs, i, fn):
        return float(fn([r[i] for r in rs])) if rs else "-"
    return label + [len(good), agg(good, 5, max), agg(good, 3, min), agg(good, 4, lambda v: 1000 * max(v)),
                    len(wrong), agg(wrong, 5, min), agg(wrong, 3, max),
                    sum(1 for r in res if not r[0] and not r[2]), sum(1 for r in res if r[0] and r[2])]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=4)
    args = ap.parse_args()
    warm_dense()
    cfg = IcpConfig()
    rows = [row([scene, k, method], runs(scene, k, method, args.seeds))
            for scene in SCENES for k in (0.0, 0.25, 1.0) for method in ("projective", "kdtree")]
    print(f"ICP ends at truth or elsewhere: {len(SIZES)} start sizes {SIZES} deg/cm x {args.seeds} seeds; "
          f"defaults min_inlier_share={cfg.min_inlier_share}, max_rms={cfg.max_rms}, "
          f"max_condition={cfg.max_condition:g}")
    print_table(["scene", "noise", "method", "truth n", "max cond", "min share", "max rms mm",
                 "elsewhere n", "min cond", "max share", "accepted elsewhere", "rejected at truth"], rows)


if __name__ == "__main__":
    run_recorded(main)
