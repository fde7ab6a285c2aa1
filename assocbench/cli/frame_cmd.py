"""``assocbench frame``: one frame as an image with its ground truth drawn, as the run's track
pictures it (``Pictures.frame_picture``): a rendered image with its true projections and
detections, a top view with the scan and its features."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..harness.config import load_run_config, run_spec, with_pictures
from ..viz.draw import IMAGE_FORMATS, check_image_path, write_image
from .common import add_run_options, check_cache, check_output_file, resolution

NAME = "frame"
HELP = ("draw one frame with its ground truth, as the run's track pictures it (a rendered image with its "
        "detections, a top view with the scan), as a PNG, or JPEG etc. by extension")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_run_options(p)
    p.add_argument("--index", type=int, default=0, help="frame index along the trajectory")
    p.add_argument("--resolution", help="WIDTHxHEIGHT of a rendered frame (a track with an image size), default 640x480")
    p.add_argument("-o", "--output", default="frame.png",
                   help=f"image file to write; its extension picks the format ({', '.join(IMAGE_FORMATS)})")


def main(args: argparse.Namespace) -> int:
    output = check_output_file(Path(args.output), check_image_path)   # before rendering: no time wasted
    cfg = load_run_config(args.config, args.sets, track=args.track, scene=args.scene, trajectory=args.trajectory,
                          frames=args.frames, seed=args.seed, resolution=resolution(args.resolution))
    spec = with_pictures(run_spec(cfg), "frame")
    check_cache(spec.source)   # before rendering: the rendered sequence is cached
    image, line = spec.track_impl.frame_picture(spec, args.index)
    write_image(output, image)
    print(line)
    print(f"wrote {output}")
    return 0
