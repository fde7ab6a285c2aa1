"""``assocbench run``: one method on one scene; per-frame and summary CSVs under results/runs/."""

from __future__ import annotations

import argparse
import sys
from functools import partial
from pathlib import Path

import pandas as pd
from scipy.spatial.transform import Rotation

from ..atomic import write_group
from ..harness.config import load_run_config, run_spec
from ..tracks.dense.spec import DenseRunSpec
from ..harness.runner import execute
from ..scoring.aggregate import OK, SUMMARY_COLUMNS
from ..scoring.loop_summary import LOOP_COLUMNS
from ..scoring.trajectory import tum_text
from .common import add_run_options, check_output_folder, config_digest, print_table

NAME = "run"
HELP = "run one associator on one scene and print its scores"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", help="associator name (assocbench list) or pkg.module:Class")
    add_run_options(p)
    p.add_argument("--out", help="output folder (default results/runs/<scene>-<method>-seed<seed>-<config digest>)")
    p.add_argument("--format", choices=("table", "csv", "json"), default="table", help="how to print the summary")


def default_out(cfg: dict, scene: str, method: str, seed: int) -> Path:
    """``results/runs/<scene>-<method>-seed<seed>-<digest>``: the digest covers every setting, so a
    quick experiment (``--frames 3``, ``--set ...``) never overwrites another run's files."""
    tag = f"{Path(scene).stem}-{method.replace(':', '.').replace('/', '.')}-seed{seed}-{config_digest(cfg)}"
    return Path("results/runs") / tag


def tum_writers(frames: pd.DataFrame, out: Path) -> dict:
    """Writers of ``truth.txt`` and ``estimate.txt`` (TUM: ``t x y z qx qy qz qw``, one line per
    frame, t = frame index in seconds), for ``evo_ape tum truth.txt estimate.txt``."""
    def writer(prefix: str):
        p = frames[[f"{prefix}{c}" for c in ("x", "y", "z")]].to_numpy(dtype=float)
        R = Rotation.from_quat(frames[[f"{prefix}{c}" for c in ("qx", "qy", "qz", "qw")]].to_numpy(dtype=float))
        text = tum_text(frames["frame"].to_numpy(dtype=float), R.as_matrix(), p, out / f"{prefix}trajectory")
        return lambda path: Path(path).write_text(text)
    return {out / "truth.txt": writer("true_"), out / "estimate.txt": writer("est_")}


def main(args: argparse.Namespace) -> int:
    cfg = load_run_config(args.config, args.sets, method=args.method, scene=args.scene,
                          trajectory=args.trajectory, frames=args.frames, seed=args.seed, loop=args.loop)
    spec = run_spec(cfg)
    out = check_output_folder(Path(args.out) if args.out else default_out(cfg, spec.sequence.scene, spec.method,
                                                                           spec.seed))
    if isinstance(spec, DenseRunSpec):
        return dense_main(spec, out, args.format)
    frames, summary = execute(spec)
    columns = SUMMARY_COLUMNS + (LOOP_COLUMNS if spec.loop else ())
    row = {"scene": spec.sequence.scene, "trajectory": spec.sequence.resolved_trajectory(),
           "method": spec.method, "seed": spec.seed, "loop": spec.estimator.mode if spec.loop else "open",
           **{k: summary[k] for k in columns}}
    summary_df = pd.DataFrame([row])
    writers = {out / name: partial(df.to_csv, index=False, float_format="%.9g")   # all files or none
               for name, df in (("frames.csv", frames), ("summary.csv", summary_df))}
    if spec.loop:
        writers |= tum_writers(frames, out)
    write_group(writers)
    if args.format == "table":
        print(f"{row['method']} on {row['scene']} ({row['trajectory']}, {row['frames']} frames, seed {row['seed']})")
        print_table(pd.DataFrame({"metric": list(summary), "value": list(summary.values())}), "table")
        extra = f", {out / 'truth.txt'} and {out / 'estimate.txt'} (TUM)" if spec.loop else ""
        print(f"wrote {out / 'frames.csv'}, {out / 'summary.csv'}{extra}")
    else:
        print_table(summary_df, args.format)
    if summary["status"] != OK:
        errors = sorted(set(frames["error"]) - {""})
        first = f" (first error: {errors[0]})" if errors else ""
        print(f"assocbench: warning: these numbers cannot be trusted: {summary['status']}{first}", file=sys.stderr)
        return 1
    return 0


def dense_main(spec: DenseRunSpec, out: Path, fmt: str) -> int:
    """The dense track's run: frames.csv, summary.csv, TUM trajectories, map.ply and map.png."""
    from ..harness.dense_execute import dense_writers, execute_dense
    from ..tracks.dense.summary import DENSE_COLUMNS

    frames, summary, end = execute_dense(spec)
    seq = spec.sequence
    row = {"scene": seq.scene, "trajectory": seq.camera_spec().resolved_trajectory(), "method": spec.method,
           "seed": spec.seed, "tracking": spec.dense.tracking, **{k: summary[k] for k in DENSE_COLUMNS}}
    summary_df = pd.DataFrame([row])
    title = f"{spec.method} on {Path(seq.scene).stem}, {spec.dense.tracking} tracking, seed {spec.seed}"
    writers = {out / n: partial(df.to_csv, index=False, float_format="%.9g")
               for n, df in (("frames.csv", frames), ("summary.csv", summary_df))}
    write_group(writers | dense_writers(frames, end, out, title))
    if fmt == "table":
        print(f"{title} ({row['trajectory']}, {row['frames']} frames)")
        print_table(pd.DataFrame({"metric": list(summary), "value": list(summary.values())}), "table")
        print(f"wrote {out / 'frames.csv'}, {out / 'summary.csv'}, {out / 'truth.txt'} and {out / 'estimate.txt'} "
              f"(TUM), {out / 'map.ply'}, {out / 'map.png'}")
    else:
        print_table(summary_df, fmt)
    if summary["status"] != OK:
        print(f"assocbench: warning: these numbers cannot be trusted: {summary['status']}", file=sys.stderr)
        return 1
    return 0
