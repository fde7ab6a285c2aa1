"""Depth sensor cost per frame: ``FrameRenderer.render_depth`` (depth + segmentation passes, no RGB)
beside ``render`` (RGB alone), and ``depth_sensor.depth_frame`` (stride, truth, noise, dropouts,
vertex and normal maps), on each dense scene along its default trajectory.

Columns (milliseconds per frame, median and p95 over ``--frames`` poses, one core):

* ``rgb``: ``render`` (the camera track's pass); ``depth+seg``: ``render_depth``;
* ``depth_frame``: ``depth_frame`` at the default ``DepthConfig`` (downsample 2);
* ``valid``: median share of the downsampled pixels with a vertex and a normal.

Usage: python benchmarks/depth_sensor_rate.py [--frames 20] [--size 640 480] [--msaa 0]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _util import print_table, run_recorded, summary_ms

from assocbench.sim.render import FrameRenderer
from assocbench.sim.scene import load_scene
from assocbench.sim.scenegen.dense import DENSE_SCENES
from assocbench.tracks.camera.sequence import SequenceSpec, trajectory_poses
from assocbench.tracks.dense.depth_sensor import depth_frame
from assocbench.tracks.dense.settings import DepthConfig


def timed(fn) -> tuple[float, object]:
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def measure(name: str, frames: int, width: int, height: int, msaa: int | None) -> list[object]:
    scene = load_scene(name)
    rots, pos = trajectory_poses(SequenceSpec(scene=name, frames=frames, width=width, height=height), scene)
    cfg = DepthConfig()
    rgb, render, sense, valid = [], [], [], []
    with FrameRenderer(scene, width, height, msaa) as renderer:
        renderer.render_depth(rots[0], pos[0])   # the first pass of each mode sets up GL state
        renderer.render(rots[0], pos[0])
        for k, (R, p) in enumerate(zip(rots, pos)):
            rgb.append(timed(lambda: renderer.render(R, p))[0])
            dt, (depth, geom) = timed(lambda: renderer.render_depth(R, p))
            render.append(dt)
            rng = np.random.default_rng([0, k, 17])
            dt, frame = timed(lambda: depth_frame(depth, geom, R, p, renderer.K, cfg, rng))
            sense.append(dt)
            valid.append(frame.valid.mean())
    return [name, *summary_ms(rgb), *summary_ms(render), *summary_ms(sense), float(np.median(valid))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--size", type=int, nargs=2, default=[640, 480], metavar=("W", "H"))
    ap.add_argument("--msaa", type=int, default=None, help="multisamples (default: the scene's, 4)")
    args = ap.parse_args()
    rows = [measure(name, args.frames, *args.size, args.msaa) for name in DENSE_SCENES]
    w, h = args.size
    print(f"{w}x{h}, msaa {'scene (4)' if args.msaa is None else args.msaa}, {args.frames} frames of the default "
          f"trajectory; ms per frame (median, p95), one core")
    print_table(["scene", "rgb", "p95", "depth+seg", "p95", "depth_frame", "p95", "valid"], rows)


if __name__ == "__main__":
    run_recorded(main)
