"""The lab-8 picture of one association: what an associator did, at a glance.

Predicted landmarks are ``+`` markers with their 3σ ellipses: blue when associated, bright red
when not. Features are green ``×`` when associated, dark red dots when not.
"""

from __future__ import annotations

import numpy as np

from ..association.compatibility import marginal_blocks
from ..association.problem import Problem
from . import draw


def draw_association(rgb: np.ndarray, problem: Problem, association: np.ndarray, title: str = "") -> np.ndarray:
    """A copy of ``rgb`` (H, W, 3) uint8 with ``association`` of ``problem`` drawn on it."""
    img = np.ascontiguousarray(rgb, dtype=np.uint8).copy()
    used = np.zeros(problem.m, bool)
    used[association[association >= 0]] = True
    for i in np.flatnonzero(~used):
        draw.dot(img, problem.z[i], draw.DARK_RED, 2)
    blocks = marginal_blocks(problem) if problem.n else np.zeros((0, 2, 2))
    for j in range(problem.n):
        color = draw.BLUE if association[j] >= 0 else draw.RED
        draw.ellipse(img, problem.zhat[j], blocks[j], color, nsigma=3.0)
        draw.plus(img, problem.zhat[j], color, size=6, thickness=2)
    for i in np.flatnonzero(used):
        draw.cross(img, problem.z[i], draw.GREEN, size=5, thickness=2)
    if title:
        draw.label(img, title)
    return img
