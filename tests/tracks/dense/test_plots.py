"""The dense map's top view draws at most ``MAX_DRAWN`` points and says when it drew a subsample."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure

from assocbench.tracks.dense.plots import MAX_DRAWN, map_panel


@pytest.mark.parametrize("n", [MAX_DRAWN, MAX_DRAWN + 1, 2 * MAX_DRAWN - 1, 216_293])
def test_at_most_max_drawn_points_and_the_label_says_how_many(n):
    """The step was ``N // MAX_DRAWN``: 39 999 points drew all 39 999, bays' 216 293 drew 21 630."""
    rng = np.random.default_rng(0)
    positions, error_mm = rng.uniform(0, 5, (n, 3)), rng.uniform(0, 30, n)
    path = np.zeros((2, 3))
    ax = Figure().subplots()
    drawn = len(map_panel(ax, positions, error_mm, path, path, "t").get_offsets())
    assert drawn <= MAX_DRAWN and drawn >= MAX_DRAWN // 2
    label = ax.get_xlabel()
    assert label.startswith("x (m)")
    assert (f"{drawn:,} of {n:,} map points drawn" in label) == (n > MAX_DRAWN), label
