"""One rendered frame with its truth: true projections, detections and their labels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import UserError
from ...sim.render import FrameRenderer
from ...sim.scene import load_scene
from ...viz import draw
from .sequence import SequenceSpec, process_frame, trajectory_poses


@dataclass
class TruthFrame:
    rgb: np.ndarray
    projections: np.ndarray
    visible: np.ndarray
    in_view: np.ndarray
    features: np.ndarray
    labels: np.ndarray

    def summary(self) -> str:
        """One line of nested counts: labelled ⊆ visible ⊆ in view, labelled ⊆ features
        (``visible``: in front, in the image, facing the camera, unoccluded; each visible landmark
        labels at most one feature)."""
        lab = self.labels >= 0
        err = np.linalg.norm(self.features[lab] - self.projections[self.labels[lab]], axis=1)
        med = f"{np.median(err):.2f} px" if len(err) else "n/a"
        n_vis, n_lab = int(self.visible.sum()), int(lab.sum())
        hidden = int((self.in_view & ~self.visible).sum())
        return (f"{n_vis} landmarks visible, {n_lab} of them labelled (detected), {n_vis - n_lab} not detected; "
                f"{hidden} more in view but hidden or turned away; {len(self.features)} features, "
                f"{len(self.features) - n_lab} unlabelled; median label error {med}")


def render_truth_frame(spec: SequenceSpec, index: int) -> TruthFrame:
    """Render frame ``index`` of ``spec``'s trajectory alone, detect and label it."""
    scene = load_scene(spec.scene)
    if not 0 <= index < spec.frames:
        raise UserError(f"--index {index} is outside the trajectory's 0..{spec.frames - 1}; raise --frames or lower it")
    rots, pos = trajectory_poses(spec, scene)
    with FrameRenderer(scene, spec.width, spec.height, spec.msaa) as renderer:
        f = process_frame(spec, scene, renderer, rots[index], pos[index], index)
        K = renderer.K
    in_front = (scene.landmarks - pos[index]) @ rots[index][:, 2] > 0
    in_view = K.in_image(np.nan_to_num(f.projections, nan=-1e9)) & in_front
    return TruthFrame(f.rgb, f.projections, f.visible, in_view, f.features, f.labels)


TRUTH_LEGEND = (
    (lambda img, p: draw.plus(img, p, draw.GREEN), "landmark, visible"),
    (lambda img, p: draw.cross(img, p, draw.MAGENTA), "landmark, hidden/turned away"),
    (lambda img, p: draw.ring(img, p, draw.YELLOW, 6, 2), "feature, labelled"),
    (lambda img, p: draw.dot(img, p, draw.DARK_RED), "feature, unlabelled"),
)


def draw_truth_frame(tf: TruthFrame, title: str = "") -> np.ndarray:
    """Green ``+`` visible landmarks' true projections, magenta ``×`` those in view but hidden or
    turned away, yellow rings on labelled features, dark-red dots on clutter; every mark outlined;
    title and key first, so they hide no mark."""
    img = tf.rgb.copy()
    if title:
        draw.label(img, title)
    hidden = np.flatnonzero(tf.in_view & ~tf.visible)
    shown = tf.projections[np.flatnonzero(tf.in_view)]
    draw.legend(img, TRUTH_LEGEND, draw.legend_box(img, TRUTH_LEGEND, np.vstack([shown, tf.features])))
    for j in hidden:
        draw.cross(img, tf.projections[j], draw.MAGENTA, size=5, thickness=2)
    for i, f in enumerate(tf.features):
        if tf.labels[i] >= 0:
            draw.ring(img, f, draw.YELLOW, 9, 2)   # wider than the + inside it
        else:
            draw.dot(img, f, draw.DARK_RED)
    for j in np.flatnonzero(tf.visible):
        draw.plus(img, tf.projections[j], draw.GREEN)
    return img
