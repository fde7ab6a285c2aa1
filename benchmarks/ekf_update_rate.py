"""EKF updates per second of the camera EKF-SLAM (``CameraEKF``) on one core, against the
textbook dense Joseph form on the same inputs.

States are synthetic (no rendering): N landmarks, ``--in-view`` × m of them 2–6 m in front of the
camera (the problem's candidates) and the rest behind it; a random positive definite covariance
with correlated landmarks (``A Aᵀ / d + 0.1 I``, scaled to σ ≈ 5 cm and 1°); m candidates
paired with features at their predicted pixels plus 1 px noise. Columns (calls per second):

* ``update``: ``CameraEKF.update`` (Joseph update + error-state injection + bookkeeping) on a
  filter restored, untimed, before each call;
* ``frame``: the whole frame, ``predict`` (odometry) + ``problem`` + ``update``;
* ``joseph``: ``ekf_core.joseph_update`` alone; ``before``: the expansion it replaced,
  ``P − K Uᵀ − U Kᵀ + K S Kᵀ`` with ``cho_factor``/``cho_solve``, then ``½ (P' + P'ᵀ)``;
* ``textbook``: ``P' = (I − K H) P (I − K H)ᵀ + K R Kᵀ`` with the dense n × n ``I − K H``, the
  full-width H and an explicit ``S⁻¹`` (``K = P Hᵀ S⁻¹``), same H, ν and R;
* ``update ÷ textbook`` and ``joseph ÷ textbook``: ratios taken within each repeat (the
  functions are timed in turn, so a slow spell of a shared machine hits them alike), median;
* ``max |dP|``: largest entry of ``P'_joseph − P'_textbook``, and that over ``max |P'|``
  (the corrections δx are asserted equal to 1e-8 relative).

Figures are the median over ``--repeats`` of ``--calls`` calls each.
Usage: python benchmarks/ekf_update_rate.py [--repeats 7] [--calls 200] [--cases 50 12 200 30]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, as the target is stated

import argparse  # noqa: E402
import copy  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import numpy as np  # noqa: E402
from _util import print_table, run_recorded  # noqa: E402
from scipy.linalg import cho_factor, cho_solve  # noqa: E402

from assocbench.estimators.base import FrameData, Motion  # noqa: E402
from assocbench.estimators.config import EstimatorConfig  # noqa: E402
from assocbench.estimators.ekf_core import joseph_update  # noqa: E402
from assocbench.models.camera import Intrinsics  # noqa: E402
from assocbench.tracks.camera.ekf import CameraEKF  # noqa: E402

K = Intrinsics.from_fovy(640, 480, 60.0)
TARGET = 1000.0   # updates/s at 50 landmarks


def random_covariance(rng: np.random.Generator, n_lm: int) -> np.ndarray:
    """PD covariance of ``[δp, δθ, l₁ … l_N]``: ``A Aᵀ / d`` (correlated) plus a floor, scaled so
    positions have σ ≈ 5 cm and angles σ ≈ 1°."""
    d = 6 + 3 * n_lm
    A = rng.normal(size=(d, d))
    P = A @ A.T / d + 0.1 * np.eye(d)
    s = np.full(d, 0.05)
    s[3:6] = np.deg2rad(1.0)
    return P * np.outer(s, s)


def make_filter(seed: int, n_lm: int, n_pair: int, in_view: float) -> tuple[CameraEKF, FrameData, np.ndarray]:
    """A filter with ``n_lm`` landmarks, ``min(n_lm, in_view · n_pair)`` of them ahead of the camera
    (the problem's candidates) and the rest behind it, a frame in which ``n_pair`` candidates are
    seen (predicted pixel + 1 px noise) among 3 clutter points, and the association pairing them."""
    rng = np.random.default_rng([seed, n_lm, n_pair])
    n_view = min(n_lm, int(np.ceil(in_view * n_pair)))
    depth = rng.uniform(2.0, 6.0, n_lm) * np.where(np.arange(n_lm) < n_view, 1.0, -1.0)
    lm = np.column_stack([rng.uniform(-0.5, 0.5, (n_lm, 2)) * np.abs(depth)[:, None], depth])
    normals = np.tile([0.0, 0.0, -1.0], (n_lm, 1))
    cfg = EstimatorConfig(mode="slam", confirm_after=2, drop_after=10**3)
    ekf = CameraEKF(K, cfg, np.eye(3), np.zeros(3), random_covariance(rng, n_lm), lm, normals, np.arange(n_lm))
    uv = K.f * lm[:n_view, :2] / lm[:n_view, 2:] + [K.cx, K.cy]
    seen = rng.choice(n_view, n_pair, replace=False)
    z = np.vstack([uv[seen] + rng.normal(0, 1.0, (n_pair, 2)), rng.uniform([0, 0], [640, 480], (3, 2))])
    frame = FrameData(z, np.repeat(np.eye(2)[None], len(z), axis=0))
    rows = ekf.problem(frame).landmark_ids   # ids are state rows here
    ekf._last = None
    assert len(rows) == n_view, "the landmarks ahead must all be candidates"
    where = {int(r): j for j, r in enumerate(seen)}
    association = np.array([where.get(int(r), -1) for r in rows], dtype=np.int64)
    return ekf, frame, association


def update_inputs(ekf: CameraEKF, frame: FrameData, association: np.ndarray):
    """``(H, cols, ν, R)`` of the update ``CameraEKF.update`` makes from ``association``."""
    ekf.problem(frame)
    rows, h, J_pose, J_l, _ = ekf._last
    ekf._last = None
    paired = np.flatnonzero(association >= 0)
    H, cols = ekf._bundle_jacobian(J_pose[paired], J_l[paired]), ekf._columns(rows[paired])
    nu = (frame.z[association[paired]] - h[paired]).ravel()
    return H, cols, nu, np.kron(np.eye(len(paired)), frame.R[0])


def textbook_joseph(P: np.ndarray, H_full: np.ndarray, nu: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The textbook update: ``S = H P Hᵀ + R``, ``K = P Hᵀ S⁻¹``,
    ``P' = (I − K H) P (I − K H)ᵀ + K R Kᵀ``, ``δx = K ν``."""
    S = H_full @ P @ H_full.T + R
    gain = P @ H_full.T @ np.linalg.inv(S)
    A = np.eye(len(P)) - gain @ H_full
    return gain @ nu, A @ P @ A.T + gain @ R @ gain.T


def before_joseph(P: np.ndarray, H: np.ndarray, cols: np.ndarray, nu: np.ndarray, R: np.ndarray):
    """``joseph_update`` as it was before this benchmark: ``P − K Uᵀ − U Kᵀ + K S Kᵀ``."""
    U = P[:, cols] @ H.T
    S = H @ U[cols] + R
    S = 0.5 * (S + S.T)
    K_gain = cho_solve(cho_factor(S, lower=True), U.T).T
    KU = K_gain @ U.T
    P_new = P - KU - KU.T + K_gain @ S @ K_gain.T
    return K_gain @ nu, 0.5 * (P_new + P_new.T)


def rates(fns: dict[str, tuple[Callable, Callable]], calls: int, repeats: int) -> dict[str, np.ndarray]:
    """Calls per second of each ``fn(setup())`` (``setup`` untimed), ``repeats`` values each; the
    functions take turns within a repeat."""
    out = {name: np.zeros(repeats) for name in fns}
    for r in range(repeats):
        for name, (fn, setup) in fns.items():
            spent = 0.0
            for _ in range(calls):
                arg = setup()
                start = time.perf_counter()
                fn(arg)
                spent += time.perf_counter() - start
            out[name][r] = calls / spent
    return out


def same_posterior(P: np.ndarray, H: np.ndarray, cols: np.ndarray, nu: np.ndarray,
                   R: np.ndarray) -> tuple[float, float]:
    """max |P'_joseph − P'_textbook| and max |P'_textbook| (δx asserted equal)."""
    H_full = np.zeros((len(H), len(P)))
    H_full[:, cols] = H
    dx_a, P_a = joseph_update(P, H, cols, nu, R)
    dx_b, P_b = textbook_joseph(P, H_full, nu, R)
    assert np.allclose(dx_a, dx_b, rtol=1e-8, atol=1e-12 * np.max(np.abs(dx_b))), "the corrections differ"
    return float(np.max(np.abs(P_a - P_b))), float(np.max(np.abs(P_b)))


def measure(n_lm: int, n_pair: int, in_view: float, calls: int, repeats: int) -> list[object]:
    """One row of the table."""
    ekf, frame, association = make_filter(0, n_lm, n_pair, in_view)
    motion = Motion(np.array([0.01, 0.0, 0.0, 0.0, 0.002, 0.0]), EstimatorConfig().odometry_covariance)

    def fresh() -> CameraEKF:
        f = copy.copy(ekf)
        f.P, f.book = ekf.P.copy(), copy.deepcopy(ekf.book)
        return f

    def with_problem() -> CameraEKF:
        f = fresh()
        f.problem(frame)
        return f

    def whole_frame(f: CameraEKF) -> None:
        f.predict(motion)
        f.problem(frame)
        f.update(association)

    H, cols, nu, R = update_inputs(fresh(), frame, association)
    H_full = np.zeros((len(H), len(ekf.P)))
    H_full[:, cols] = H
    P = ekf.P
    got = rates({"update": (lambda f: f.update(association), with_problem),
                 "frame": (whole_frame, fresh),
                 "joseph": (lambda P: joseph_update(P, H, cols, nu, R), lambda: P),
                 "before": (lambda P: before_joseph(P, H, cols, nu, R), lambda: P),
                 "textbook": (lambda P: textbook_joseph(P, H_full, nu, R), lambda: P)}, calls, repeats)
    diff, scale = same_posterior(P, H, cols, nu, R)
    med = {name: float(np.median(v)) for name, v in got.items()}
    names = ("update", "frame", "joseph", "before", "textbook")
    return [n_lm, n_pair, len(association), *(f"{med[k]:.0f}" for k in names),
            f"{np.median(got['update'] / got['textbook']):.1f}x", f"{np.median(got['joseph'] / got['textbook']):.1f}x",
            f"{np.median(got['joseph'] / got['before']):.1f}x", f"{diff:.1e}", f"{diff / scale:.1e}"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--calls", type=int, default=200)
    ap.add_argument("--cases", type=int, nargs="+", default=[50, 12, 50, 30, 200, 12, 200, 30],
                    help="pairs: landmarks in the state, paired features")
    ap.add_argument("--in-view", type=float, default=1.5, help="candidates per paired feature")
    args = ap.parse_args()
    if len(args.cases) % 2:
        ap.error("--cases takes pairs: landmarks paired [landmarks paired ...]")
    rows = [measure(n, m, args.in_view, args.calls, args.repeats) for n, m in zip(args.cases[::2], args.cases[1::2])]
    print(f"CameraEKF updates per second, one core, median of {args.repeats} x {args.calls} calls "
          f"(target >= {TARGET:.0f} updates/s at 50 landmarks)")
    print_table(["landmarks", "paired", "candidates", "update/s", "frame/s", "joseph/s", "before/s", "textbook/s",
                 "update÷textbook", "joseph÷textbook", "joseph÷before", "max |dP|", "rel"], rows)


if __name__ == "__main__":
    run_recorded(main)
