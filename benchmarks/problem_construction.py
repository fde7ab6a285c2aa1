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

Where construction's time goes (``now`` split in two, timed in the same run):

* checks: the validation proper, what decides a refusal, as the fast path runs it
  (``_plain_views``): eight identity tests of the types, then one compiled call for the layout,
  the shapes and the screen of every ``R_i`` and diagonal block of P (``_screen_blocks``, one
  Cholesky attempt per block), and the four views;
* object: the rest, ``now - checks``: the read-only views, the ids, the scalars, the instance.
  This part is Python's floor (about 2 µs on these machines), whatever n.

Range-bearing EKF scans (``range_bearing_problem``; P is (2n, 2n)); median over the problems of
the best of 5; one core.

Usage: python benchmarks/problem_construction.py [--problems 10] [--sizes 10 20 40 80 160 320]
"""
# ruff: noqa: I001  (_util goes first: it sets one BLAS thread before numpy loads)

from __future__ import annotations

import argparse
import os

from _util import print_table, run_recorded, summary_ms, time_call

import numpy as np

from assocbench import Problem, make_associator
from assocbench.association import problem as problem_module
from assocbench.models.synthetic import range_bearing_problem


def best_per_call(fn, calls: int = 200) -> float:
    """Best of 5 of the mean wall time of ``calls`` calls (s): a single microsecond call is below
    the clock's resolution."""
    return time_call(lambda: [fn() for _ in range(calls)], 5) / calls


def construction_times(p: Problem) -> tuple[float, float, float, float]:
    """(before, now, now + validate, checks) seconds to construct a problem with ``p``'s arrays."""
    z, R, zhat, P = (np.array(a) for a in (p.z, p.R, p.zhat, p.P))      # writeable, as a caller's are
    copies = lambda: (z.copy(), R.copy(), zhat.copy(), P.copy())        # noqa: E731
    before = best_per_call(lambda: Problem(*copies(), volume=p.volume, angular=p.angular).validate())
    now = best_per_call(lambda: Problem(z, R, zhat, P, volume=p.volume, angular=p.angular))
    checked = best_per_call(lambda: Problem(z, R, zhat, P, volume=p.volume, angular=p.angular).validate())
    # the validation proper, as construction runs it (private helpers: a breakdown, not an API)
    checks = best_per_call(lambda: problem_module._plain_views(z, R, zhat, P))
    return before, now, checked, checks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=10)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 80, 160, 320])
    args = ap.parse_args()
    mnn = make_associator("mnn")
    rows = []
    for n in args.sizes:
        times = {"before": [], "now": [], "validate": [], "checks": [], "mnn": []}
        for s in range(args.problems):
            p, _ = range_bearing_problem(np.random.default_rng(1000 * n + s), n=n)
            before, now, checked, checks = construction_times(p)
            times["before"].append(before)
            times["now"].append(now)
            times["validate"].append(max(checked - now, 0.0))
            times["checks"].append(checks)
            mnn.associate(p)
            times["mnn"].append(best_per_call(lambda p=p: mnn.associate(p)))
        b, c, v, k, a = (1e3 * summary_ms(t)[0] for t in times.values())      # µs
        rows.append([n, b, c, b / c, k, c - k, a, c / a, k / a, v])
    print(f"Problem construction, median µs over {args.problems} range-bearing problems (best of 5 of the "
          f"mean of 200 calls each); load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print_table(["n", "before µs (copy + whole P)", "now µs", "before / now", "checks µs", "object µs",
                 "mnn call µs", "now / mnn", "checks / mnn", "validate µs (harness, once)"], rows)


if __name__ == "__main__":
    run_recorded(main)
