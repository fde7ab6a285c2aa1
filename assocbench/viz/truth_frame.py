"""One rendered frame with its truth: true projections, detections and their labels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sim.detect import detect
from ..sim.render import FrameRenderer
from ..sim.scene import load_scene
from ..sim.sequence import SequenceSpec
from ..sim.trajectory import make_trajectory, rig_for
from ..sim.truth import label_features, visibility
from . import draw


@dataclass
class TruthFrame:
    rgb: np.ndarray
    projections: np.ndarray
    visible: np.ndarray
    in_view: np.ndarray
    features: np.ndarray
    labels: np.ndarray

    def summary(self) -> str:
        lab = self.labels >= 0
        err = np.linalg.norm(self.features[lab] - self.projections[self.labels[lab]], axis=1)
        med = f"{np.median(err):.2f} px" if len(err) else "n/a"
        return (f"{int(self.visible.sum())} landmarks visible ({int(self.in_view.sum() - self.visible.sum())} in view "
                f"but hidden or turned away), {len(self.features)} features, {int(lab.sum())} labelled, "
                f"median label error {med}")


def render_truth_frame(spec: SequenceSpec, index: int) -> TruthFrame:
    """Render frame ``index`` of ``spec``'s trajectory alone, detect and label it."""
    scene = load_scene(spec.scene)
    if not 0 <= index < spec.frames:
        from ..errors import UserError

        raise UserError(f"--index {index} is outside the trajectory's 0..{spec.frames - 1}; raise --frames or lower it")
    rig = rig_for(scene.landmarks, scene.normals, scene.fovy, spec.width / spec.height)
    rots, pos = make_trajectory(spec.resolved_trajectory(), rig, spec.frames, spec.seed, **spec.trajectory_params)
    with FrameRenderer(scene, spec.width, spec.height) as renderer:
        frame = renderer.render(rots[index], pos[index], depth=spec.truth.occlusion == "depth")
        K = renderer.K
    features = detect(frame["rgb"], spec.detector, np.random.default_rng([spec.seed, index, 11]))
    uv, imaged, visible = visibility(scene, rots[index], pos[index], K, spec.truth, frame.get("depth"))
    in_view = K.in_image(np.nan_to_num(uv, nan=-1e9)) & ((rots[index].T @ (scene.landmarks - pos[index]).T)[2] > 0)
    labels = label_features(features, uv, imaged, spec.truth.gate_px)
    return TruthFrame(frame["rgb"], uv, visible, in_view, features, labels)


def draw_truth_frame(tf: TruthFrame, title: str = "") -> np.ndarray:
    """Green ``+`` true projections of visible landmarks, gray ``x`` for hidden ones in view,
    yellow rings on labelled features, small dark-red dots on unlabelled (clutter) features."""
    img = tf.rgb.copy()
    for j in np.flatnonzero(tf.in_view & ~tf.visible):
        draw.cross(img, tf.projections[j], draw.GRAY)
    for i, f in enumerate(tf.features):
        if tf.labels[i] >= 0:
            draw.ring(img, f, draw.YELLOW, 6)
        else:
            draw.dot(img, f, draw.DARK_RED)
    for j in np.flatnonzero(tf.visible):
        draw.plus(img, tf.projections[j], draw.GREEN)
    if title:
        draw.label(img, title)
    return img
