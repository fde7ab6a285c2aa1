"""Side by side with MRPT 2.5 (the C++ robotics library's ``data_association_full_covariance``, from
the distribution's ``libmrpt-slam-dev``): our JCBB and MNN against its JCBB and nearest neighbour,
on range-bearing EKF-SLAM scans (pose-correlated landmarks, detection 0.8, clutter 20 % of n;
``range_bearing_problem``), the same χ² gate (0.99) on both sides, one thread.

MRPT takes no measurement noise: it is given ``S = P + blockdiag(R)`` (every R_i is the same in
these scans). Its Mahalanobis test does not wrap the bearing, so pairs across ±π are outside its
gate (ours wraps): a few landmarks near the seam, counted in "its gate misses". MRPT's nearest
neighbour runs with its default KD-tree gate and with the exact gate (``use_kd_tree=false``); its
JCBB with its default. Times: ours the best of 3 Python calls (everything included), MRPT's the
best of 3 calls timed inside the C++ driver (``benchmarks/mrpt/mrpt_assoc.cpp``, built here with
g++); median over the problems. A MRPT JCBB call still running after ``--timeout`` seconds is
counted "over" and left out of its median. Every answer is checked with our joint test
(``jointly_compatible``, every pairing inside the individual gate): "JC" counts the answers that
pass, "pairings" is the mean count.

Skipped with one line where MRPT's headers or library are absent.

Usage: python benchmarks/mrpt_compare.py [--problems 20] [--sizes 10 20 40 160] [--timeout 10]
"""
# ruff: noqa: I001  (_util goes first: it sets one BLAS thread before numpy loads)

from __future__ import annotations

import argparse
import glob
import os
import shutil
import subprocess
import sys
from pathlib import Path

from _util import print_table, run_recorded, time_call

import numpy as np

from assocbench import Problem, make_associator
from assocbench.association.compatibility import individually_compatible, jointly_compatible
from assocbench.models.synthetic import range_bearing_problem

HERE = Path(__file__).resolve().parent / "mrpt"
DRIVER = HERE / "build" / "mrpt_assoc"
CONFIDENCE = 0.99


def build_driver() -> str | None:
    """Build the driver if needed; the reason it cannot be, or None."""
    source = HERE / "mrpt_assoc.cpp"
    if DRIVER.exists() and DRIVER.stat().st_mtime >= source.stat().st_mtime:
        return None
    includes = sorted(glob.glob("/usr/include/mrpt/*/include"))
    if not includes or not glob.glob("/usr/lib/*/libmrpt-slam.so*") or shutil.which("g++") is None:
        return "MRPT (libmrpt-slam-dev) or g++ not found"
    DRIVER.parent.mkdir(exist_ok=True)
    cmd = ["g++", "-O2", "-std=c++17", *(f"-I{d}" for d in includes), str(source), "-o", str(DRIVER),
           "-lmrpt-slam", "-lmrpt-math", "-lmrpt-core"]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    return None if done.returncode == 0 else f"building the MRPT driver failed: {done.stderr.strip()[:200]}"


def mrpt_call(problem: Problem, method: str, kdtree: bool, timeout: float) -> tuple[float, np.ndarray, int] | None:
    """(ms, association (n,), pairs inside its gate) of one MRPT call; None past ``timeout``."""
    d, n = problem.d, problem.n
    S = problem.P + np.kron(np.eye(n), problem.R[0])
    head = f"{problem.m} {n} {d} {method} {int(kdtree)} 3 {CONFIDENCE}\n"
    body = "\n".join(" ".join(repr(float(v)) for v in a.ravel()) for a in (problem.z, problem.zhat, S))
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    try:
        done = subprocess.run([str(DRIVER)], input=head + body + "\n", capture_output=True, text=True,
                              timeout=timeout, env=env, check=True)
    except subprocess.TimeoutExpired:
        return None
    out = np.full(n, -1, np.int64)
    ms, compatible = np.nan, 0
    for line in done.stdout.splitlines():
        key, *vals = line.split()
        if key == "ms":
            ms = float(vals[0])
        elif key == "compatible":
            compatible = int(vals[0])
        elif key == "pair":
            out[int(vals[1])] = int(vals[0])
    return ms, out, compatible


def passes(problem: Problem, association: np.ndarray, ic: np.ndarray) -> bool:
    """Every pairing inside our individual gate and the whole jointly compatible."""
    j = np.flatnonzero(association >= 0)
    return bool(np.all(ic[association[j], j]) and jointly_compatible(problem, association, CONFIDENCE))


def measure(n: int, problems: int, timeout: float) -> list[list]:
    ours = {"jcbb": make_associator("jcbb", confidence=CONFIDENCE), "mnn": make_associator("mnn", confidence=CONFIDENCE)}
    theirs = {"MRPT JCBB": ("jcbb", True), "MRPT NN (KD-tree gate)": ("nn", True), "MRPT NN (exact gate)": ("nn", False)}
    stats = {name: {"ms": [], "jc": 0, "pairs": [], "over": 0, "missed": []} for name in [*ours, *theirs]}
    for s in range(problems):
        problem, _ = range_bearing_problem(np.random.default_rng(1000 * n + s), n=n)
        assert np.allclose(problem.R, problem.R[0]), "MRPT takes one R"
        ic = individually_compatible(problem, CONFIDENCE)
        for name, assoc in ours.items():
            out = assoc.associate(problem)
            entry = stats[name]
            entry["ms"].append(1e3 * time_call(lambda a=assoc, p=problem: a.associate(p), 3))
            entry["jc"] += passes(problem, out, ic)
            entry["pairs"].append(int(np.sum(out >= 0)))
            entry["missed"].append(0.0)
        for name, (method, kdtree) in theirs.items():
            entry = stats[name]
            got = mrpt_call(problem, method, kdtree, timeout)
            if got is None:
                entry["over"] += 1
                continue
            ms, out, compatible = got
            entry["ms"].append(ms)
            entry["jc"] += passes(problem, out, ic)
            entry["pairs"].append(int(np.sum(out >= 0)))
            entry["missed"].append(1.0 - compatible / max(int(ic.sum()), 1))
    rows = []
    for name, e in stats.items():
        done = len(e["ms"])
        rows.append([n, name, float(np.median(e["ms"])) if done else float("nan"), f"{e['over']}/{problems}",
                     f"{e['jc']}/{done}", float(np.mean(e["pairs"])) if done else float("nan"),
                     f"{100 * float(np.mean(e['missed'])):.1f} %" if done else "-"])
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 160])
    ap.add_argument("--timeout", type=float, default=10.0, help="seconds a MRPT JCBB call may run")
    args = ap.parse_args()
    reason = build_driver()
    if reason is not None:
        print(f"mrpt_compare: skipped, {reason}")
        sys.exit(0)
    load = os.getloadavg()[0]
    rows = [row for n in args.sizes for row in measure(n, args.problems, args.timeout)]
    print(f"ms per problem, median over {args.problems} range-bearing problems per n (confidence {CONFIDENCE}); "
          "'its gate misses': share of the pairs inside the exact (wrapped) gate that its gate left out; "
          f"load average {load:.1f} at the start, {os.getloadavg()[0]:.1f} at the end, {os.cpu_count()} CPUs")
    print_table(["n", "method", "median ms", "over timeout", "JC", "pairings", "its gate misses"], rows)
    print("ours / MRPT, the medians' ratio (below 1: ours faster; JCBB only where MRPT finished every problem)")
    print_table(["n", "jcbb / MRPT JCBB", "mnn / MRPT NN (KD-tree gate)", "mnn / MRPT NN (exact gate)"],
                [ratios(n, [r for r in rows if r[0] == n]) for n in args.sizes])


def ratios(n: int, rows: list[list]) -> list:
    """One row of the ratio table from ``measure``'s rows of one n."""
    ms = {r[1]: r[2] for r in rows}
    finished = {r[1]: r[3].startswith("0/") for r in rows}
    jcbb = ms["jcbb"] / ms["MRPT JCBB"] if finished["MRPT JCBB"] else "MRPT over timeout"
    return [n, jcbb, ms["mnn"] / ms["MRPT NN (KD-tree gate)"], ms["mnn"] / ms["MRPT NN (exact gate)"]]


if __name__ == "__main__":
    run_recorded(main)
