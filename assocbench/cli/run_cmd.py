"""``assocbench run``: one method on one scene; per-frame and summary CSVs under results/runs/."""

from __future__ import annotations

import argparse
import sys
import tempfile
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from ..atomic import write_group
from ..harness.config import load_run_config, run_spec
from ..harness.runner import describe_run
from ..harness.sandbox import execute
from ..scoring.aggregate import OK
from ..scoring.loop_summary import BAND_MARKS, band_side
from ..scoring.trajectory import tum_text
from ..tracks.capabilities import RunFiles, has
from .common import add_run_options, check_cache, check_output_folder, config_digest, print_table, unit_of

NAME = "run"
HELP = "run one associator on one scene and print its scores"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", help="associator name (assocbench list) or pkg.module:Class")
    add_run_options(p)
    p.add_argument("--out", help="output folder (default results/runs/<scene>-<method>-seed<seed>-<config digest>)")
    p.add_argument("--format", choices=("table", "csv", "json"), default="table", help="how to print the summary")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="a progress bar over the frames on stderr (default: when stderr is a terminal)")


def default_out(cfg: dict, scene: str, method: str, seed: int) -> Path:
    """``results/runs/<scene>-<method>-seed<seed>-<digest>``: the digest covers every setting, so a
    quick experiment (``--frames 3``, ``--set ...``) never overwrites another run's files."""
    tag = f"{Path(scene).stem}-{method.replace(':', '.').replace('/', '.')}-seed{seed}-{config_digest(cfg)}"
    return Path("results/runs") / tag


def tum_writers(frames: pd.DataFrame, out: Path, truth: str = "truth") -> dict:
    """Writers of ``truth.txt`` and ``estimate.txt`` (TUM, t = frame index in seconds) for
    ``evo_ape tum truth.txt estimate.txt``; a frame without a pose has no line in either. ``truth``:
    the first file's name (a recorded track's ``reference``)."""
    columns = [f"{p}{c}" for p in ("true_", "est_") for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]
    frames = frames[np.isfinite(frames[columns].to_numpy(dtype=float)).all(axis=1)]

    def writer(prefix: str):
        p = frames[[f"{prefix}{c}" for c in ("x", "y", "z")]].to_numpy(dtype=float)
        R = Rotation.from_quat(frames[[f"{prefix}{c}" for c in ("qx", "qy", "qz", "qw")]].to_numpy(dtype=float))
        text = tum_text(frames["frame"].to_numpy(dtype=float), R.as_matrix(), p, out / f"{prefix}trajectory")
        return lambda path: Path(path).write_text(text)
    return {out / f"{truth}.txt": writer("true_"), out / "estimate.txt": writer("est_")}


def source_labels(source) -> dict:
    """What a simulated source's path was (``trajectory``: the resolved name), for the summary."""
    resolve = getattr(getattr(source, "spec", None), "resolved_trajectory", None)
    return {"trajectory": resolve()} if callable(resolve) else {}
def band_note(summary: dict, metric: str) -> str:
    """For the ``anees`` row of the table: where it lies against its band, when outside."""
    if metric != "anees":
        return ""
    side = band_side(summary["anees"], summary.get("anees_lo", np.nan), summary.get("anees_hi", np.nan))
    what = {"above": "overconfident", "below": "pessimistic"}.get(side)
    return f"; {BAND_MARKS[side]} {side} its 95 % band: {what}" if side else ""


def main(args: argparse.Namespace) -> int:
    cfg = load_run_config(args.config, args.sets, track=args.track, method=args.method, scene=args.scene,
                          trajectory=args.trajectory, frames=args.frames, seed=args.seed, loop=args.loop)
    spec = run_spec(cfg)
    check_cache(spec.source)
    track = spec.track_impl
    out = check_output_folder(Path(args.out) if args.out else default_out(cfg, spec.source.name, spec.method,
                                                                           spec.seed))
    with tempfile.TemporaryDirectory(prefix="assocbench-run-") as artifacts:   # end-of-run files of the worker
        show = sys.stderr.isatty() if args.progress is None else args.progress
        frames, summary = execute(spec, artifacts=Path(artifacts), progress=show)
        labels, words = describe_run(track, spec)
        row = {"track": track.name, "scene": spec.source.name, **source_labels(spec.source),
               "method": spec.method, "seed": spec.seed, **labels,
               **{k: summary[k] for k in track.columns(spec.loop).summary}}
        summary_df = pd.DataFrame([row])
        path = f", trajectory {row['trajectory']}" if "trajectory" in row else ""
        against = track.columns(spec.loop).scored_against
        title = f"{row['method']} on {row['scene']} ({track.name} track): {words}{path}, {row['frames']} frames, " \
                f"seed {row['seed']}" + ("" if against == "truth" else f", scored against the {against}")
        writers = {out / name: partial(df.to_csv, index=False, float_format="%.9g")   # all files or none
                   for name, df in (("frames.csv", frames), ("summary.csv", summary_df))}
        if "est_x" in frames:   # an estimated trajectory (a closed loop, a track that tracks): TUM files for evo
            writers |= tum_writers(frames, out, against)
        if has(track, RunFiles):
            writers |= track.run_files(frames, Path(artifacts), out, title)
        write_group(writers)
    if args.format == "table":
        print(title)
        units = track.columns(spec.loop).units
        print_table(pd.DataFrame({"metric": list(summary), "value": list(summary.values()),
                                  "unit": [(units.get(m) or unit_of(m)) + band_note(summary, m) for m in summary]}),
                    "table")
        print("wrote " + ", ".join(str(p) for p in writers))
    else:
        print_table(summary_df, args.format)
    diverged = summary.get("diverged_at", -1)
    if isinstance(diverged, (int, float)) and diverged >= 0:   # a result of the method, said in words
        # on stderr: stdout is the summary alone, which --format json or csv must keep parseable
        print(f"assocbench: note: the estimator diverged at frame {int(diverged)} (its NEES stayed above the 95 % "
              f"band): a result of {spec.method}'s pairings, counted in diverged_at, not a failure of the run; a "
              f"diverged run is chaotic: its digits may differ on another machine",
              file=sys.stderr)
    if summary["status"] != OK:
        errors = sorted(set(frames["error"]) - {""}) if "error" in frames else []
        first = f" (first error: {errors[0]})" if errors else ""
        print(f"assocbench: warning: these numbers cannot be trusted: {summary['status']}{first}", file=sys.stderr)
        return 1
    return 0
