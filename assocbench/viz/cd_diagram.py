"""A critical-difference diagram after Demšar (JMLR 7, 2006, figure 1): mean ranks on an axis (1,
the best, at the left), each method named with its rank, the critical difference as a bar, and a
thick line under each run of methods the test cannot tell apart. Laid out in inches, so every label
has its own row and the figure grows with the names."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

AXIS_WIDTH = 4.2      # inches from rank 1 to rank k
CHAR = 0.085          # inches a character of a 9 pt label takes, generously
ROW = 0.24            # inches between the rows of names
CLIQUE_STEP = 0.11    # inches between the bars of runs not told apart


def cd_figure(names: Sequence[str], mean_ranks: Sequence[float], cd: float, cliques: Sequence[Sequence[int]],
              title: str, note: str = ""):
    """The diagram of methods ``names`` at ``mean_ranks`` (1 best); ``cd``: the critical difference
    (NaN: none drawn); ``cliques``: runs of indices into ``names`` not told apart; ``note``: a
    line under the title (the test's result)."""
    from matplotlib.figure import Figure

    k = len(names)
    ranks = np.asarray(mean_ranks, dtype=float)
    labels = [f"{n} ({r:.2f})" for n, r in zip(names, ranks)]
    side = 0.35 + CHAR * max((len(t) for t in labels), default=4)
    width = AXIS_WIDTH + 2 * side
    order = [int(i) for i in np.argsort(ranks, kind="stable")]
    left, right = order[:math.ceil(k / 2)], order[math.ceil(k / 2):][::-1]   # lines must not cross
    axis_y = 0.95 if note else 0.8
    first_row = axis_y + 0.3 + CLIQUE_STEP * len(cliques)
    height = first_row + ROW * max(len(left), len(right), 1) + 0.1
    fig = Figure(figsize=(width, height))
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set(xlim=(0, width), ylim=(height, 0))
    ax.axis("off")

    def x(rank: float) -> float:
        return side + AXIS_WIDTH * (rank - 1) / max(k - 1, 1)

    ax.text(width / 2, 0.08, title, ha="center", va="top", fontsize=10, weight="bold")
    if note:
        ax.text(width / 2, 0.3, note, ha="center", va="top", fontsize=8, color="0.3")
    ax.plot([x(1), x(max(k, 2))], [axis_y, axis_y], color="k", lw=1)
    for r in range(1, max(k, 2) + 1):
        ax.plot([x(r), x(r)], [axis_y, axis_y - 0.06], color="k", lw=1)
        ax.text(x(r), axis_y - 0.08, str(r), ha="center", va="bottom", fontsize=8)
    if np.isfinite(cd) and k > 1:
        bar_y = axis_y - 0.38
        ax.plot([x(1), x(1 + cd)], [bar_y, bar_y], color="k", lw=1.5)
        ax.text(x(1 + cd) + 0.08, bar_y, f"CD = {cd:.2f}", ha="left", va="center", fontsize=8)
    for c, run in enumerate(cliques):
        y = axis_y + 0.2 + CLIQUE_STEP * c
        ax.plot([x(ranks[list(run)].min()) - 0.04, x(ranks[list(run)].max()) + 0.04], [y, y], color="k", lw=3,
                solid_capstyle="butt")
    for side_order, edge, ha in ((left, side - 0.12, "right"), (right, width - side + 0.12, "left")):
        for row, i in enumerate(side_order):
            y = first_row + ROW * (row + 0.5)
            ax.plot([x(ranks[i]), x(ranks[i]), edge], [axis_y, y, y], color="0.25", lw=0.9)
            ax.text(edge + (-0.05 if ha == "right" else 0.05), y, labels[i], ha=ha, va="center", fontsize=9)
    return fig
