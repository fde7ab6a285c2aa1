"""Problem construction time against n, beside an MNN call on the same problem for scale.

Construction checks what every associator reads (each R_i, each diagonal block of P:
``_screen_blocks``, O(m d³ + n d³)) and keeps views of float64 inputs; the whole of P (finite,
symmetric, positive semidefinite, O((nd)³)) is ``Problem.validate()``'s, once per problem,
which the harness calls before any method runs (its own cost, not a method's). Timed in the
same run:

* before: what construction did until issue 28 item 2 — copy every array and check the whole
  of P at once (here ``Problem(copies).validate()``, which also runs the block screen: at most
  a few percent of it);
* now: ``Problem(z, R, zhat, P)``;
* validate: ``validate()`` on a fresh problem (the harness's check, once per frame).

Range-bearing EKF scans (``range_bearing_problem``; P is (2n, 2n)); median over the problems of
the best of 5; one core.

Usage: python benchmarks/problem_construction.py [--problems 10] [--sizes 10 20 40 80 160 320]
"""
# ruff: noqa: I001  (_util goes first: it sets one BLAS thread before numpy loads)

from __future__ import annotations

import argparse
import os

from _util import print_table, summary_ms, time_call

import numpy as np

from assocbench import Problem, make_associator
from assocbench.models.synthetic import range_bearing_problem


def construction_times(p: Problem) -> tuple[float, float, float]:
    """(before, now, now + validate) best-of-5 seconds to construct a problem with ``p``'s arrays."""
    z, R, zhat, P = (np.array(a) for a in (p.z, p.R, p.zhat, p.P))      # writeable, as a caller's are
    copies = lambda: (z.copy(), R.copy(), zhat.copy(), P.copy())        # noqa: E731
    before = time_call(lambda: Problem(*copies(), volume=p.volume, angular=p.angular).validate(), 5)
    now = time_call(lambda: Problem(z, R, zhat, P, volume=p.volume, angular=p.angular), 5)
    checked = time_call(lambda: Problem(z, R, zhat, P, volume=p.volume, angular=p.angular).validate(), 5)
    return before, now, checked


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=10)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 80, 160, 320])
    args = ap.parse_args()
    mnn = make_associator("mnn")
    rows = []
    for n in args.sizes:
        times = {"before": [], "now": [], "validate": [], "mnn": []}
        for s in range(args.problems):
            p, _ = range_bearing_problem(np.random.default_rng(1000 * n + s), n=n)
            before, now, checked = construction_times(p)
            times["before"].append(before)
            times["now"].append(now)
            times["validate"].append(max(checked - now, 0.0))
            mnn.associate(p)
            times["mnn"].append(time_call(lambda p=p: mnn.associate(p), 5))
        b, c, v, a = (summary_ms(t)[0] for t in times.values())
        rows.append([n, b, c, b / c, a, c / a, v])
    print(f"Problem construction, median ms over {args.problems} range-bearing problems (best of 5 each); "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print_table(["n", "before ms (copy + whole P)", "now ms", "before / now", "mnn call ms", "now / mnn",
                 "validate ms (harness, once)"], rows)


if __name__ == "__main__":
    main()
