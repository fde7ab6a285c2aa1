"""Options and output helpers shared by several commands."""

from __future__ import annotations

import argparse
import json

import pandas as pd

from ..errors import UserError


def add_run_options(p: argparse.ArgumentParser) -> None:
    """The flags that pick a sequence and a belief (see configs/default.yaml)."""
    p.add_argument("--scene", help="shipped scene name or path to an MJCF file")
    p.add_argument("--trajectory", help="circle | line | figure-eight | loop")
    p.add_argument("--frames", type=int, help="number of frames")
    p.add_argument("--seed", type=int, help="seed of trajectory jitter, belief errors and clutter")
    p.add_argument("--config", help="YAML run config (default: the shipped configs/default.yaml)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", dest="sets",
                   help="override a config key, e.g. --set belief.sigma_rotation=2 (repeatable)")


def resolution(text: str | None) -> list[int] | None:
    if text is None:
        return None
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UserError(f"--resolution expects WIDTHxHEIGHT such as 640x480, got {text!r}") from None
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
