"""``assocbench render``: a video of a run with the lab-8 association overlay."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..associators.registry import make_associator
from ..belief.camera_belief import make_problem
from ..harness.config import load_run_config, run_spec
from ..harness.runner import call_method
from ..sim.render import FrameRenderer
from ..sim.scene import load_scene
from ..sim.sequence import load_sequence
from ..viz.overlay import draw_association
from ..viz.video import check_fps, check_video_path, write_video
from .common import add_run_options

NAME = "render"
HELP = "write a video (.mp4 or .gif) of a run with the association drawn on every frame"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", help="associator name or pkg.module:Class")
    add_run_options(p)
    p.add_argument("-o", "--output", default="run.mp4", help="video file, .mp4 or .gif")
    p.add_argument("--fps", type=float, default=8.0, help="frames per second, in (0, 100]")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    """Render the run; exit 1 (after writing the video) when the method failed on any frame.
    Each answer goes through ``run``'s plugin boundary (``call_method``: a private copy of the
    problem, anything raised or an invalid association is that frame's failure); the method runs
    in this process, so ``time_limit_s`` is not enforced here."""
    output = Path(args.output)
    check_video_path(output)
    fps = check_fps(args.fps)
    cfg = load_run_config(args.config, args.sets, method=args.method, scene=args.scene,
                          trajectory=args.trajectory, frames=args.frames, seed=args.seed)
    spec = run_spec(cfg)
    seq = load_sequence(spec.sequence)
    associator = make_associator(spec.method, **spec.params)
    failures: list[str] = []

    def frames():
        with FrameRenderer(load_scene(spec.sequence.scene), spec.sequence.width, spec.sequence.height,
                           spec.sequence.msaa) as r:
            bar = tqdm(range(len(seq)), desc=f"render {spec.method}", unit="frame",
                       disable=args.quiet or not sys.stderr.isatty())
            for k in bar:
                problem, truth = make_problem(seq, k, spec.belief, spec.seed)
                association, _, _, error = call_method(associator, problem)   # run's boundary and checks
                if association is None:
                    association = np.full(problem.n, -1, dtype=np.int64)
                rgb = r.render(seq.rotations[k], seq.positions[k])["rgb"]
                if error:
                    failures.append(f"frame {k}: {error}")
                    yield draw_association(rgb, problem, association, f"{spec.method} frame {k}: FAILED", error)
                    continue
                tp = int(((association >= 0) & (association == truth.association)).sum())
                fp = int(((association >= 0) & (association != truth.association)).sum())
                yield draw_association(rgb, problem, association, f"{spec.method} frame {k}: {tp} right, {fp} wrong")

    count = write_video(output, frames(), fps)
    print(f"wrote {output} ({count} frames)")
    if failures:
        print(f"assocbench: {spec.method} failed on {len(failures)} of {count} frames (drawn as failed, "
              f"nothing associated); first: {failures[0]}", file=sys.stderr)
        return 1
    return 0
