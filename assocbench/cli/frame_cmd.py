"""``assocbench frame``: one rendered frame as an image with true projections and detections drawn."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..harness.config import camera_only, load_run_config, run_spec
from ..tracks.camera.truth_frame import draw_truth_frame, render_truth_frame
from ..viz.draw import IMAGE_FORMATS, check_image_path, write_image
from .common import add_run_options, check_output_file, resolution

NAME = "frame"
HELP = "render one frame with its ground truth drawn on it (PNG, or JPEG etc. by extension)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_run_options(p)
    p.add_argument("--index", type=int, default=0, help="frame index along the trajectory")
    p.add_argument("--resolution", help="WIDTHxHEIGHT, default 640x480")
    p.add_argument("-o", "--output", default="frame.png",
                   help=f"image file to write; its extension picks the format ({', '.join(IMAGE_FORMATS)})")


def main(args: argparse.Namespace) -> int:
    output = check_output_file(Path(args.output), check_image_path)   # before rendering: no time wasted
    cfg = load_run_config(args.config, args.sets, scene=args.scene, trajectory=args.trajectory,
                          frames=args.frames, seed=args.seed, resolution=resolution(args.resolution))
    spec = camera_only(run_spec(cfg), "frame").sequence
    tf = render_truth_frame(spec, args.index)
    title = f"{spec.scene} {spec.resolved_trajectory()} frame {args.index}"
    write_image(output, draw_truth_frame(tf, title))
    print(f"{title}: {tf.summary()}")
    print(f"wrote {output}  (green +: true projection, yellow ring: labelled feature, "
          f"dark red dot: unlabelled feature, magenta x: landmark in view but hidden or turned away)")
    return 0
