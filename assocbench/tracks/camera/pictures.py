"""What ``assocbench frame`` and ``render`` draw on the camera track: a rendered frame with its
truth; a run's frames with the lab-8 overlay and, closed loop, a top view beside."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from ...sim.render import FrameRenderer
from ...sim.scene import load_scene
from ...viz.overlay import draw_association
from ..capabilities import RunFrame
from .sequence import Sequence
from .topview import top_view, view_bounds
from .truth_frame import draw_truth_frame, render_truth_frame

TRUTH_KEY = ("green +: true projection, yellow ring: labelled feature, dark red dot: unlabelled feature, "
             "magenta x: landmark in view but hidden or turned away")


def frame_picture(spec, index: int) -> tuple[np.ndarray, str]:
    """Frame ``index`` rendered alone, detected and labelled, its truth drawn (``truth_frame``)."""
    seq = spec.source.spec
    tf = render_truth_frame(seq, index)
    title = f"{seq.scene} {seq.resolved_trajectory()} frame {index}"
    return draw_truth_frame(tf, title), f"{title}: {tf.summary()}\n({TRUTH_KEY})"


def landmark_blocks(P: np.ndarray, n: int) -> np.ndarray:
    """The (n, 3, 3) diagonal blocks of the landmarks in a state ``[pose (6), l₁ (3), …, lₙ (3)]``."""
    if n == 0:
        return np.zeros((0, 3, 3))
    L = P[6:6 + 3 * n, 6:6 + 3 * n].reshape(n, 3, n, 3)
    idx = np.arange(n)
    return L[idx, :, idx, :].copy()


def top_view_width(bounds, height: int) -> int:
    """Top view width beside an image of ``height``: the box's aspect, within 3/4 to 2 heights, even
    (MP4)."""
    aspect = (bounds[1] - bounds[0]) / (bounds[3] - bounds[2])
    return 2 * int(round(np.clip(aspect, 0.75, 2.0) * height / 2))


def _title(method: str, rf: RunFrame) -> tuple[str, str]:
    """The overlay's title and failure note of a recorded frame."""
    if rf.error:
        return f"{method} frame {rf.k}: FAILED", rf.error
    return f"{method} frame {rf.k}: {rf.record['tp']} right, {rf.record['fp']} wrong", ""


def run_pictures(spec, seq: Sequence, frames: Iterable[RunFrame]) -> Iterator[np.ndarray]:
    """Each frame re-rendered with the method's association (lab-8 colours); closed loop, beside the
    top view after that frame's update, on one box for the video."""
    s = spec.source.spec
    bounds = view_bounds(seq.positions, seq.landmarks)   # fixed for the whole video: no jumping
    size = (seq.K.height, top_view_width(bounds, seq.K.height))
    est_p = []
    with FrameRenderer(load_scene(s.scene), s.width, s.height, s.msaa) as renderer:
        for rf in frames:
            rgb = renderer.render(seq.rotations[rf.k], seq.positions[rf.k])["rgb"]
            overlay = draw_association(rgb, rf.problem, rf.association, *_title(spec.method, rf))
            if rf.estimator is None:
                yield overlay
                continue
            f, r = rf.estimator, rf.record
            est_p.append(f.p.copy())
            note = (f"frame {rf.k}: error {100 * r['pos_err']:.1f} cm, {r['rot_err_deg']:.2f} deg, "
                    f"NEES {r['nees']:.1f}, map {int(np.sum(f.book.confirmed))}")   # the filter's confirmed landmarks
            means = f.landmarks
            top = top_view(seq.positions[:rf.k + 1], np.array(est_p), f.R, seq.landmarks, means,
                           landmark_blocks(f.covariance, len(means)), f.book.confirmed, size=size, bounds=bounds,
                           true_R=seq.rotations[rf.k], title=note)
            yield np.hstack([overlay, top])
