"""Our JCBB against the textbook JCBB (benchmarks/textbook_jcbb.py): identical hypotheses
asserted on every problem, speed ratio printed. Range-bearing problems, 80 % detection,
clutter 20 % of n. Usage: python benchmarks/jcbb_vs_textbook.py [--problems 20]"""

from __future__ import annotations

import argparse

import numpy as np
from _util import print_table, run_recorded, summary_ms, time_call
from textbook_jcbb import textbook_jcbb

from assocbench import make_associator
from assocbench.models.synthetic import range_bearing_problem


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--problems", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[5, 10, 15, 20])
    args = ap.parse_args()
    rows = []
    for n in args.sizes:
        ours, book = [], []
        for s in range(args.problems):
            problem, _ = range_bearing_problem(np.random.default_rng(s), n=n)
            jcbb = make_associator("jcbb", max_nodes=10**9)
            a = jcbb.associate(problem)
            b = textbook_jcbb(problem)
            assert np.array_equal(a, b), f"n={n} seed={s}: ours {a} textbook {b}"
            ours.append(time_call(lambda: jcbb.associate(problem), 3))
            book.append(time_call(lambda: textbook_jcbb(problem), 1))
        (om, op), (bm, bp) = summary_ms(ours), summary_ms(book)
        rows.append([n, om, op, bm, bp, bm / om])
    print("JCBB: ours vs textbook (identical hypotheses on every problem), ms per problem")
    print_table(["n", "ours med", "ours p95", "textbook med", "textbook p95", "speed-up (median)"], rows)


if __name__ == "__main__":
    run_recorded(main)
