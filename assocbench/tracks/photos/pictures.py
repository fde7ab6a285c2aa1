"""What ``assocbench frame`` and ``render`` draw on the photos track: the photograph at twice its
size with its keypoints, the predicted landmarks and the pairings: the reference's (``frame``) or a
method's coloured against it (``render``)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import cv2
import numpy as np

from ...association.problem import Problem
from ...association.truth import FrameTruth
from ...scoring.metrics import same_feature
from ...viz import draw
from ..capabilities import RunFrame
from .source import PhotoSource

SCALE = 2            # pictures are drawn at twice the photos' size: 400 pairings on 640 x 427 px are a blur
GREY, ORANGE = (170, 170, 170), (255, 140, 0)

FRAME_LEGEND = (
    (lambda img, p: draw.dot(img, p, GREY, 1, halo=None), "keypoint"),
    (lambda img, p: draw.plus(img, p, draw.GREEN, 4, halo=None), "prediction, reference pair (line)"),
    (lambda img, p: draw.plus(img, p, draw.MAGENTA, 4, halo=None), "prediction, no reference keypoint"),
)
RUN_LEGEND = (
    (lambda img, p: cv2.line(img, (p[0] - 6, p[1]), (p[0] + 6, p[1]), draw.GREEN, 2), "paired as the reference"),
    (lambda img, p: cv2.line(img, (p[0] - 6, p[1]), (p[0] + 6, p[1]), draw.RED, 2), "paired, not the reference"),
    (lambda img, p: cv2.line(img, (p[0] - 6, p[1]), (p[0] + 6, p[1]), ORANGE, 2), "reference pair left out"),
    (lambda img, p: draw.dot(img, p, GREY, 1, halo=None), "keypoint"),
)


def photo(source: PhotoSource, k: int) -> np.ndarray:
    """Image ``k`` as RGB at ``SCALE`` times its size."""
    bgr = cv2.imread(str(source.recording().photos[k].image), cv2.IMREAD_COLOR)
    return cv2.resize(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), None, fx=SCALE, fy=SCALE, interpolation=cv2.INTER_LINEAR)


def at_scale(pixels: np.ndarray) -> np.ndarray:
    """(column, row) pixels of the photo as positions in the picture (pixel centres stay centres)."""
    return (np.asarray(pixels, float) + 0.5) * SCALE - 0.5


def _canvas(source: PhotoSource, k: int, problem: Problem, title: str, legend) -> np.ndarray:
    """The photo, its title, key and keypoints."""
    img = photo(source, k)
    draw.shade(img, 0, 0, img.shape[1], img.shape[0], draw.BLACK, 0.35)   # the marks stand out on the façade
    draw.label(img, title)
    z, zhat = at_scale(problem.z), at_scale(problem.zhat)
    draw.legend(img, legend, draw.legend_box(img, legend, np.vstack([z, zhat])))
    for p in z:
        draw.dot(img, p, GREY, 1, halo=None)
    return img


def _line(img: np.ndarray, a, b, color) -> None:
    cv2.line(img, tuple(int(round(v)) for v in a), tuple(int(round(v)) for v in b), color, 2, cv2.LINE_AA)


def reference_picture(source: PhotoSource, k: int, problem: Problem, truth: FrameTruth, title: str) -> np.ndarray:
    """Image ``k`` with each candidate's prediction and a line to its reference keypoint."""
    img = _canvas(source, k, problem, title, FRAME_LEGEND)
    z, zhat = at_scale(problem.z), at_scale(problem.zhat)
    for j, i in enumerate(truth.association):
        if i >= 0:
            _line(img, zhat[j], z[i], draw.YELLOW)
        draw.plus(img, zhat[j], draw.GREEN if i >= 0 else draw.MAGENTA, 4, halo=None)
    return img


def decision_picture(source: PhotoSource, rf: RunFrame, title: str) -> np.ndarray:
    """Image ``rf.k`` with the method's pairings, green where the reference agrees, red where not,
    orange the reference's it left out."""
    problem, truth, a = rf.problem, rf.truth, rf.association
    img = _canvas(source, rf.k, problem, title, RUN_LEGEND)
    z, zhat = at_scale(problem.z), at_scale(problem.zhat)
    right = same_feature(a, truth.association, truth.feature_labels)
    for j in range(problem.n):
        if a[j] >= 0:
            _line(img, zhat[j], z[a[j]], draw.GREEN if right[j] else draw.RED)
        elif truth.association[j] >= 0:
            _line(img, zhat[j], z[truth.association[j]], ORANGE)
    return img


def frame_picture(run, index: int) -> tuple[np.ndarray, str]:
    """Frame ``index`` with its reference drawn, and one line of what it shows."""
    source = run.source
    problem, truth = run.track_impl.problem(source, index, run)
    pairs = int(np.sum(truth.association >= 0))
    title = f"{source.name} image {index + 1}: {problem.n} predicted landmarks, {problem.m} keypoints, {pairs} reference pairs"
    return reference_picture(source, index, problem, truth, title), title + " (" + source.recording().report.line() + ")"


def run_pictures(run, source: PhotoSource, frames: Iterable[RunFrame]) -> Iterator[np.ndarray]:
    """Each recorded frame with the method's decisions."""
    for rf in frames:
        if rf.error:
            title = f"{run.method} image {rf.k + 1}: FAILED ({rf.error[:60]})"
        else:
            title = (f"{run.method} image {rf.k + 1}: {rf.record['tp']} as the reference, {rf.record['fp']} not, "
                     f"{rf.record['fn']} reference pairs left out")
        yield decision_picture(source, rf, title)
