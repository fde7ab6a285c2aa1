"""The lab-8 picture of one association: predicted landmarks as ``+`` with 3σ ellipses, blue when
associated, red when not; features as green ``×`` when associated, dark red dots when not; a key,
and on a failed frame its reason in a red box.
"""

from __future__ import annotations

import numpy as np

from ..association.compatibility import marginal_blocks
from ..association.problem import Problem
from . import draw

OVERLAY_LEGEND = (
    (lambda img, p: (draw.ellipse(img, p, np.eye(2) * 9, draw.BLUE, 1.5),
                     draw.plus(img, p, draw.BLUE, size=5, thickness=2, halo=None)), "predicted, associated"),
    (lambda img, p: draw.plus(img, p, draw.RED, size=5, thickness=2, halo=None), "predicted, unassociated"),
    (lambda img, p: draw.cross(img, p, draw.GREEN, size=4, thickness=2, halo=None), "feature, associated"),
    (lambda img, p: draw.dot(img, p, draw.DARK_RED), "feature, unassociated"),
)


def draw_association(rgb: np.ndarray, problem: Problem, association: np.ndarray, title: str = "",
                     failure: str = "") -> np.ndarray:
    """A copy of ``rgb`` with ``association`` of ``problem`` drawn; on ``failure`` pass an all -1
    ``association`` and the reason is written. Title, note and key go first, so they hide no mark."""
    img = np.ascontiguousarray(rgb, dtype=np.uint8).copy()
    y = draw.label(img, title) if title else 4
    if failure:
        draw.label(img, f"failed: {failure}", (4, y + 2), background=(200, 0, 0))
    box = draw.legend_box(img, OVERLAY_LEGEND, np.vstack([problem.zhat.reshape(-1, 2), problem.z.reshape(-1, 2)]))
    draw.legend(img, OVERLAY_LEGEND, box)
    used = np.zeros(problem.m, bool)
    used[association[association >= 0]] = True
    for i in np.flatnonzero(~used):
        draw.dot(img, problem.z[i], draw.DARK_RED, 2)
    blocks = marginal_blocks(problem) if problem.n else np.zeros((0, 2, 2))
    # + and × stay without an outline: a feature on its prediction would hide the other's centre
    for j in range(problem.n):
        color = draw.BLUE if association[j] >= 0 else draw.RED
        draw.ellipse(img, problem.zhat[j], blocks[j], color, nsigma=3.0)
        draw.plus(img, problem.zhat[j], color, size=6, thickness=2, halo=None)
    for i in np.flatnonzero(used):
        draw.cross(img, problem.z[i], draw.GREEN, size=5, thickness=2, halo=None)
    return img
