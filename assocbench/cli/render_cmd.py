"""``assocbench render``: a video of a run, a picture per frame drawn by its track
(``Pictures.run_pictures``): rendered frames with the lab-8 overlay (closed loop: beside a top
view), or a top view with the scan and each feature coloured by the method's decision."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tqdm import tqdm

from ..harness.config import load_run_config, run_spec, with_pictures
from ..harness.loop_replay import replay_run
from ..harness.sandbox import execute
from ..viz.video import check_fps, check_video_path, write_video
from .common import add_run_options, check_cache, check_output_file

NAME = "render"
HELP = ("write a video (.mp4 or .gif) of a run, each frame as its track pictures it: the association drawn "
        "on the rendered image (with --loop beside a top view of the trajectories and the map), or a top view "
        "with the scan and each feature coloured by the method's decision")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", help="associator name or pkg.module:Class")
    add_run_options(p)
    p.add_argument("-o", "--output", default="run.mp4", help="video file, .mp4 or .gif")
    p.add_argument("--fps", type=float, default=8.0, help="frames per second, in (0, 100]")
    p.add_argument("--quiet", action="store_true", help="no progress bars (there are none when stderr is not a terminal)")


def main(args: argparse.Namespace) -> int:
    """Render the run; exit 1 (after writing the video) when the method failed on any frame. The
    method runs as in ``run`` (a worker, ``time_limit_s``, private copies, answers validated); this
    process only draws, replaying each frame from the recorded associations."""
    output = check_output_file(Path(args.output), check_video_path)
    fps = check_fps(args.fps)
    cfg = load_run_config(args.config, args.sets, track=args.track, method=args.method, scene=args.scene,
                          trajectory=args.trajectory, frames=args.frames, seed=args.seed, loop=args.loop)
    spec = with_pictures(run_spec(cfg), "render")
    check_cache(spec.source)   # before the run warms kernels and renders
    track = spec.track_impl
    bars = not args.quiet and sys.stderr.isatty()   # the run's, then the drawing's
    records, _ = execute(spec, associations=True, progress=bars)
    failures = [f"frame {r.frame}: {r.error}" for r in records.itertuples() if r.error]
    pictures = track.run_pictures(spec, spec.source, replay_run(spec, records))
    count = write_video(output, tqdm(pictures, total=len(records), desc=f"render {spec.method}", unit="frame",
                                     disable=not bars), fps)
    print(f"wrote {output} ({count} frames)")
    if failures:
        print(f"assocbench: {spec.method} failed on {len(failures)} of {count} frames (drawn as failed, "
              f"nothing associated); first: {failures[0]}", file=sys.stderr)
        return 1
    return 0
