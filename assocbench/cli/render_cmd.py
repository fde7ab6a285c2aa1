"""``assocbench render``: a video of a run with the lab-8 association overlay."""

from __future__ import annotations

import argparse
from pathlib import Path

from tqdm import tqdm

from ..associators.registry import make_associator
from ..belief.camera_belief import make_problem
from ..harness.config import load_run_config, run_spec
from ..sim.render import FrameRenderer
from ..sim.scene import load_scene
from ..sim.sequence import load_sequence
from ..viz.overlay import draw_association
from ..viz.video import check_video_path, write_video
from .common import add_run_options

NAME = "render"
HELP = "write a video (.mp4 or .gif) of a run with the association drawn on every frame"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", help="associator name or pkg.module:Class")
    add_run_options(p)
    p.add_argument("-o", "--output", default="run.mp4", help="video file, .mp4 or .gif")
    p.add_argument("--fps", type=float, default=8.0, help="frames per second")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    output = Path(args.output)
    check_video_path(output)
    cfg = load_run_config(args.config, args.sets, method=args.method, scene=args.scene,
                          trajectory=args.trajectory, frames=args.frames, seed=args.seed)
    spec = run_spec(cfg)
    seq = load_sequence(spec.sequence)
    associator = make_associator(spec.method, **spec.params)

    def frames():
        with FrameRenderer(load_scene(spec.sequence.scene), spec.sequence.width, spec.sequence.height,
                           spec.sequence.msaa) as r:
            for k in tqdm(range(len(seq)), desc=f"render {spec.method}", unit="frame", disable=args.quiet):
                problem, truth = make_problem(seq, k, spec.belief, spec.seed)
                association = associator.associate(problem)
                tp = int(((association >= 0) & (association == truth.association)).sum())
                fp = int(((association >= 0) & (association != truth.association)).sum())
                rgb = r.render(seq.rotations[k], seq.positions[k])["rgb"]
                yield draw_association(rgb, problem, association, f"{spec.method} frame {k}: {tp} right, {fp} wrong")

    count = write_video(output, frames(), args.fps)
    print(f"wrote {output} ({count} frames)")
    return 0
