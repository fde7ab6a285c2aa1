"""``assocbench render``: a video of a run with the lab-8 association overlay."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..belief.camera_belief import make_problem
from ..harness.config import load_run_config, run_spec
from ..harness.runner import execute
from ..sim.render import FrameRenderer
from ..sim.scene import load_scene
from ..sim.sequence import load_sequence
from ..viz.overlay import draw_association
from ..viz.video import check_fps, check_video_path, write_video
from .common import add_run_options, check_output_file

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
    The method runs as in ``run`` (``execute``: a worker process, ``time_limit_s`` per call, a
    private copy of each problem, every answer validated); this process only draws."""
    output = check_output_file(Path(args.output), check_video_path)
    fps = check_fps(args.fps)
    cfg = load_run_config(args.config, args.sets, method=args.method, scene=args.scene,
                          trajectory=args.trajectory, frames=args.frames, seed=args.seed)
    spec = run_spec(cfg)
    records, _ = execute(spec, associations=True)
    seq = load_sequence(spec.sequence)   # cached by execute: nothing is rendered twice
    failures = [f"frame {r.frame}: {r.error}" for r in records.itertuples() if r.error]

    def frames():
        with FrameRenderer(load_scene(spec.sequence.scene), spec.sequence.width, spec.sequence.height,
                           spec.sequence.msaa) as renderer:
            bar = tqdm(records.itertuples(), total=len(records), desc=f"render {spec.method}", unit="frame",
                       disable=args.quiet or not sys.stderr.isatty())
            for r in bar:
                problem, _ = make_problem(seq, r.frame, spec.belief, spec.seed)
                rgb = renderer.render(seq.rotations[r.frame], seq.positions[r.frame])["rgb"]
                association = np.asarray(r.association, dtype=np.int64)
                if r.error:
                    yield draw_association(rgb, problem, association, f"{spec.method} frame {r.frame}: FAILED", r.error)
                else:
                    yield draw_association(rgb, problem, association,
                                           f"{spec.method} frame {r.frame}: {r.tp} right, {r.fp} wrong")

    count = write_video(output, frames(), fps)
    print(f"wrote {output} ({count} frames)")
    if failures:
        print(f"assocbench: {spec.method} failed on {len(failures)} of {count} frames (drawn as failed, "
              f"nothing associated); first: {failures[0]}", file=sys.stderr)
        return 1
    return 0
