"""Options and output helpers shared by several commands."""

from __future__ import annotations

import argparse
import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from ..errors import UserError
from ..scoring.units import unit_of  # noqa: F401  (run's table imports it from here)
from ..sim.settings import MIN_SIDE  # a zero side made a rendering rig divide by zero


def add_run_options(p: argparse.ArgumentParser) -> None:
    """The flags that pick a sequence and a belief (every setting: docs/reference/settings.md)."""
    p.add_argument("--track", help="the run's track (assocbench list tracks); default: the method's own track, else "
                   "the scene's, else the default track")
    p.add_argument("--scene", help="a scene or dataset the track ships (assocbench list scenes), or a file of the "
                   "track's kind (an MJCF, a log)")
    p.add_argument("--trajectory", help="a simulated track's path through its scene, by name (assocbench list "
                   "trajectories: each with its tracks)")
    p.add_argument("--frames", type=int, help="number of frames")
    p.add_argument("--seed", type=int, help="seed of trajectory jitter, belief errors and clutter")
    p.add_argument("--config", help="YAML run config, merged on the track's defaults (docs/reference/settings.md)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", dest="sets",
                   help="override a config key, e.g. --set belief.sigma_rotation=2 (repeatable)")
    p.add_argument("--loop", action="store_true", default=None,
                   help="closed loop: the belief is the estimator's posterior (the scene's EKF: SLAM, or "
                        "localisation on the known map for lines scenes), updated with the method's own pairings; "
                        "settings under estimator.* (mode: localisation | slam)")




def resolution(text: str | None) -> list[int] | None:
    """``WIDTHxHEIGHT`` (e.g. ``640x480``) as ``[width, height]``; None passes through.
    Both sides must be integers of at least 16 pixels (the upper bound is the scene's buffer)."""
    if text is None:
        return None
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UserError(f"--resolution expects WIDTHxHEIGHT such as 640x480, got {text!r}") from None
    if w < MIN_SIDE or h < MIN_SIDE:
        raise UserError(f"--resolution {text} is too small: width and height must be at least {MIN_SIDE} pixels, "
                        f"e.g. 640x480")
    return [w, h]


def print_table(df: pd.DataFrame, fmt: str) -> None:
    """Print a data frame as an aligned table, CSV or JSON records."""
    if fmt == "csv":
        print(df.to_csv(index=False, float_format="%.6g"), end="")
    elif fmt == "json":
        print(json.dumps(json.loads(df.to_json(orient="records", double_precision=6)), indent=2))
    else:
        with pd.option_context("display.width", 200, "display.max_columns", 50, "display.float_format", "{:.4g}".format):
            print(df.to_string(index=False))


def check_output_folder(path: Path, flag: str = "--out") -> Path:
    """Refuse, before anything runs, an output folder that could not be created or written; create
    nothing (a run that fails must not leave an empty folder behind)."""
    probe = path
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise UserError(f"cannot create output folder {path}: {probe} is a file; choose another {flag}")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise UserError(f"cannot write output folder {path}: {probe} is not writable; choose another {flag}")
    return path


def check_output_file(path: Path, check_format: Callable[[Path], object]) -> Path:
    """Refuse, before anything renders, an ``-o`` file whose name or folder cannot be written."""
    check_format(path)
    check_output_folder(path.parent, "-o")
    return path


def config_digest(cfg: dict) -> str:
    """8 hex digits naming a resolved run config: runs that differ in any setting never share a folder."""
    text = json.dumps(cfg, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:8]


def check_cache(*sources) -> None:
    """``atomic.check_cache_folder`` with the sequence cache's subfolder of each source that has one:
    a file where one belongs (``$ASSOCBENCH_CACHE/<track>``) stops the command before it compiles or
    renders."""
    from ..atomic import check_cache_folder

    check_cache_folder(*sorted({f for s in sources if (f := getattr(s, "cache_folder", None))}))
