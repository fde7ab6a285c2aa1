"""Frames per second of the simulation pipeline (render + detect + label, the cheapest truth
path: RGB and mj_ray) at 320x240 and 640x480, with the scene's multisampling and without
(``msaa: 0``), and of association (problem + associate) per method, on one core.
Usage: python benchmarks/pipeline_fps.py [--frames 60] [--scene room]"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _util import print_table, run_recorded

from assocbench.associators.registry import geometric_builtins, make_associator
from assocbench.belief.config import BeliefConfig
from assocbench.harness.runner import warm_up
from assocbench.sim.render import FrameRenderer
from assocbench.sim.scene import load_scene
from assocbench.sim.trajectory import make_trajectory, rig_for
from assocbench.tracks.camera.belief import make_problem
from assocbench.tracks.camera.detect import detect
from assocbench.tracks.camera.sequence import SequenceSpec, load_sequence
from assocbench.tracks.camera.settings import DetectorConfig, TruthConfig
from assocbench.tracks.camera.truth import label_features, visibility


def pipeline(scene_name: str, width: int, height: int, frames: int, msaa: int | None) -> list[float]:
    scene = load_scene(scene_name)
    rots, pos = make_trajectory("circle", rig_for(scene.landmarks, scene.normals, scene.fovy, width / height), frames)
    det, truth = DetectorConfig(), TruthConfig()
    stages = np.zeros(3)
    with FrameRenderer(scene, width, height, msaa) as r:
        r.render(rots[0], pos[0])  # warm-up: GL context and buffers
        for k in range(frames):
            t0 = time.perf_counter()
            rgb = r.render(rots[k], pos[k])["rgb"]
            t1 = time.perf_counter()
            f = detect(rgb, det)
            t2 = time.perf_counter()
            uv, visible = visibility(scene, rots[k], pos[k], r.K, truth)
            label_features(f, uv, visible, truth.gate_px)
            t3 = time.perf_counter()
            stages += [t1 - t0, t2 - t1, t3 - t2]
    ms = stages / frames * 1e3
    return [*ms, 1e3 / ms.sum()]


def association(scene_name: str, frames: int) -> list[list[object]]:
    seq = load_sequence(SequenceSpec(scene=scene_name, frames=frames))
    cfg = BeliefConfig()
    rows = []
    for method in geometric_builtins():
        assoc = make_associator(method)
        warm_up(assoc)
        start = time.perf_counter()
        for k in range(len(seq)):
            assoc.associate(make_problem(seq, k, cfg, 0)[0])
        rows.append([method, len(seq) / (time.perf_counter() - start)])
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--scene", default="room")
    args = ap.parse_args()
    rows = [[f"{w}x{h}", "scene's" if msaa is None else msaa, *pipeline(args.scene, w, h, args.frames, msaa)]
            for w, h in ((320, 240), (640, 480)) for msaa in (None, 0)]
    print(f"pipeline on {args.scene}, {args.frames} frames, ms per frame (one core)")
    print_table(["resolution", "msaa", "render", "detect", "label (mj_ray)", "frames/s"], rows)
    print(f"association on {args.scene} (default belief), problems/s including building the problem")
    print_table(["method", "frames/s"], association(args.scene, min(args.frames, 40)))


if __name__ == "__main__":
    run_recorded(main)
