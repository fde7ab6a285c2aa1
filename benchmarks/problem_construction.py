"""Problem construction time against n: the one-pass compiled screen (finiteness, symmetry and a
Cholesky of every R and of P up to order 40, LAPACK beyond) against the two validations before it,
kept here and timed in the same run: the eigendecomposition (the first baseline) and a Cholesky
per field after numpy's finiteness test; beside an MNN call on the same problem for scale.

Range-bearing EKF scans (``range_bearing_problem``; P is (2n, 2n)); median over the problems of
the best of 5 constructions; one core.

Usage: python benchmarks/problem_construction.py [--problems 10] [--sizes 10 20 40 80 160 320]
"""
# ruff: noqa: I001  (_util goes first: it sets one BLAS thread before numpy loads)

from __future__ import annotations

import argparse
import os

from _util import print_table, summary_ms, time_call

import numpy as np

from assocbench import Problem, make_associator
from assocbench.association import problem as problem_module
from assocbench.models.synthetic import range_bearing_problem


def eigen_check_spd(name: str, mats: np.ndarray, allow_semidefinite: bool = False) -> None:
    """The validation before the Cholesky one (the baseline): every eigenvalue of the stack."""
    if mats.size == 0:
        return
    scale = max(np.abs(mats).max(), 1e-300)
    if np.abs(mats - np.swapaxes(mats, -1, -2)).max() > 1e-9 * scale:
        raise ValueError(f"Problem.{name} is not symmetric")
    eig = np.linalg.eigvalsh(mats)
    bad = eig.min(axis=-1) < (-1e-10 * scale if allow_semidefinite else 0.0)
    if np.any(bad):
        raise ValueError(f"Problem.{name} is not positive {'semi' if allow_semidefinite else ''}definite")


def eigen_screen(zhat, z, R, P, small) -> tuple[int, float]:
    """The screen before the compiled one: finiteness by numpy, then both matrices to the slow
    path (``_check_spd``, here ``eigen_check_spd``)."""
    for code, arr in enumerate((zhat, z, R, P), start=1):
        if not np.isfinite(arr.sum()) and not np.all(np.isfinite(arr)):
            return code, 0.0
    return 5, 0.0


def build(p: Problem) -> Problem:
    return Problem(z=p.z, R=p.R, zhat=p.zhat, P=p.P, volume=p.volume, angular=p.angular)


def construction_times(p: Problem) -> tuple[float, float, float]:
    """(eigen, Cholesky per field, one-pass screen) best-of-5 seconds to construct a copy of ``p``."""
    current = problem_module._check_spd, problem_module._screen
    try:
        problem_module._check_spd, problem_module._screen = eigen_check_spd, eigen_screen
        eigen = time_call(lambda: build(p), 5)
        problem_module._check_spd = current[0]
        per_field = time_call(lambda: build(p), 5)
    finally:
        problem_module._check_spd, problem_module._screen = current
    return eigen, per_field, time_call(lambda: build(p), 5)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=10)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 80, 160, 320])
    args = ap.parse_args()
    mnn = make_associator("mnn")
    rows = []
    for n in args.sizes:
        times = {"eigen": [], "per field": [], "screen": [], "mnn": []}
        for s in range(args.problems):
            p, _ = range_bearing_problem(np.random.default_rng(1000 * n + s), n=n)
            for key, t in zip(("eigen", "per field", "screen"), construction_times(p)):
                times[key].append(t)
            mnn.associate(p)
            times["mnn"].append(time_call(lambda p=p: mnn.associate(p), 5))
        e, f, c, a = (summary_ms(t)[0] for t in times.values())
        rows.append([n, e, f, c, e / c, a, c / a])
    print(f"Problem construction, median ms over {args.problems} range-bearing problems (best of 5 each); "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print_table(["n", "eigen (before) ms", "cholesky per field ms", "one-pass screen (now) ms", "eigen / now",
                 "mnn call ms", "now / mnn"], rows)


if __name__ == "__main__":
    main()
