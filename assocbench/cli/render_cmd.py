"""``assocbench render``: a video of a run with the lab-8 association overlay; with ``--loop``, each
frame's overlay beside a top view of the closed loop (trajectories, map and its uncertainty)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from ..harness.config import RunSpec, camera_only, load_run_config, run_spec
from ..harness.loop_replay import replay_loop
from ..harness.sandbox import execute
from ..sim.render import FrameRenderer
from ..sim.scene import load_scene
from ..tracks.camera.belief import make_problem
from ..tracks.camera.sequence import Sequence, load_sequence
from ..viz.overlay import draw_association
from ..viz.topview import top_view, view_bounds
from ..viz.video import check_fps, check_video_path, write_video
from .common import add_run_options, check_output_file

NAME = "render"
HELP = ("write a video (.mp4 or .gif) of a run with the association drawn on every frame; with --loop, "
        "beside a top view of the trajectories and the map")
REPLAY_TOLERANCE_M = 1e-6   # the replayed filter must put the camera where the run did


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", help="associator name or pkg.module:Class")
    add_run_options(p)
    p.add_argument("-o", "--output", default="run.mp4", help="video file, .mp4 or .gif")
    p.add_argument("--fps", type=float, default=8.0, help="frames per second, in (0, 100]")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _title(method: str, r) -> tuple[str, str]:
    """The overlay's title and failure note of a recorded frame ``r``."""
    if r.error:
        return f"{method} frame {r.frame}: FAILED", r.error
    return f"{method} frame {r.frame}: {r.tp} right, {r.fp} wrong", ""


def open_frames(spec: RunSpec, seq: Sequence, records: pd.DataFrame, rgb_of):
    """Overlays of an open-loop run: each frame's problem rebuilt from the belief's seeded errors."""
    for r in records.itertuples():
        problem, _ = make_problem(seq, r.frame, spec.belief, spec.seed)
        yield draw_association(rgb_of(r.frame), problem, np.asarray(r.association, dtype=np.int64),
                               *_title(spec.method, r))


def top_view_width(bounds, height: int) -> int:
    """Width of the top view beside a camera image of ``height``: the box's aspect, between 3/4
    and 2 heights (a corridor gets a wide picture), even (some MP4 encoders need it)."""
    aspect = (bounds[1] - bounds[0]) / (bounds[3] - bounds[2])
    return 2 * int(round(np.clip(aspect, 0.75, 2.0) * height / 2))


def loop_frames(spec: RunSpec, seq: Sequence, records: pd.DataFrame, rgb_of):
    """Side by side: the overlay of the loop's own problem and the method's recorded association,
    and the top view after that frame's update (``replay_loop`` rebuilds both in this process)."""
    rows = {r.frame: r for r in records.itertuples()}
    recorded = {k: (r.association, r.error) for k, r in rows.items()}
    bounds = view_bounds(seq.positions, seq.landmarks)   # fixed for the whole video: no jumping
    height = seq.K.height
    size = (height, top_view_width(bounds, height))
    est_p, warned = [], False
    for lf in replay_loop(spec, seq, recorded):
        if lf.k not in rows:
            continue
        r, rec = rows[lf.k], lf.record
        est_p.append(lf.p)
        drift = float(np.linalg.norm(lf.p - [r.est_x, r.est_y, r.est_z]))
        if drift > REPLAY_TOLERANCE_M and not warned:
            print(f"assocbench: warning: the replayed filter is {drift:.3g} m from the run's estimate at frame "
                  f"{lf.k}; the top view shows the replay", file=sys.stderr)
            warned = True
        overlay = draw_association(rgb_of(lf.k), lf.problem, lf.association, *_title(spec.method, r))
        note = (f"frame {lf.k}: error {100 * rec['pos_err']:.1f} cm, {rec['rot_err_deg']:.2f} deg, "
                f"NEES {rec['nees']:.1f}, map {rec['map_size']}")
        top = top_view(seq.positions[:lf.k + 1], np.array(est_p), lf.R, seq.landmarks, lf.landmarks,
                       lf.landmark_covs, lf.confirmed, size=size, bounds=bounds, true_R=seq.rotations[lf.k],
                       title=note)
        yield np.hstack([overlay, top])


def main(args: argparse.Namespace) -> int:
    """Render the run; exit 1 (after writing the video) when the method failed on any frame.
    The method runs as in ``run`` (``execute``: a worker process, ``time_limit_s`` per call, a
    private copy of each problem, every answer validated); this process only draws (a closed
    loop is replayed here with the recorded associations, the method is not called again)."""
    output = check_output_file(Path(args.output), check_video_path)
    fps = check_fps(args.fps)
    cfg = load_run_config(args.config, args.sets, method=args.method, scene=args.scene,
                          trajectory=args.trajectory, frames=args.frames, seed=args.seed, loop=args.loop)
    spec = camera_only(run_spec(cfg), "render")
    records, _ = execute(spec, associations=True)
    seq = load_sequence(spec.sequence)   # cached by execute: nothing is rendered twice
    failures = [f"frame {r.frame}: {r.error}" for r in records.itertuples() if r.error]

    def frames():
        with FrameRenderer(load_scene(spec.sequence.scene), spec.sequence.width, spec.sequence.height,
                           spec.sequence.msaa) as renderer:
            def rgb_of(k: int) -> np.ndarray:
                return renderer.render(seq.rotations[k], seq.positions[k])["rgb"]
            pictures = (loop_frames if spec.loop else open_frames)(spec, seq, records, rgb_of)
            yield from tqdm(pictures, total=len(records), desc=f"render {spec.method}", unit="frame",
                            disable=args.quiet or not sys.stderr.isatty())

    count = write_video(output, frames(), fps)
    print(f"wrote {output} ({count} frames)")
    if failures:
        print(f"assocbench: {spec.method} failed on {len(failures)} of {count} frames (drawn as failed, "
              f"nothing associated); first: {failures[0]}", file=sys.stderr)
        return 1
    return 0
