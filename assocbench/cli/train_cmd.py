"""``assocbench train``: fit the learned associator from an export (``assocbench export``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..associators.learned.train import train_model, write_model
from ..errors import UserError
from .common import check_output_file

NAME = "train"
HELP = "fit the learned associator (--method learned) from an export; writes a JSON model"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", required=True, help="an export folder (assocbench export --suite S --out DIR)")
    p.add_argument("--out", required=True, help="the model file to write (.json)")


def _json_name(path: Path) -> None:
    if path.suffix != ".json":
        raise UserError(f"--out {path}: a model is a .json file; name it MODEL.json")


def main(args: argparse.Namespace) -> int:
    out = check_output_file(Path(args.out), _json_name)
    doc = train_model(Path(args.data))
    write_model(doc, out)
    t = doc["meta"]["training"]
    print(f"wrote {out}: {len(doc['trees'])} trees of depth {doc['depth']} on {t['pairs_fitted']} pairs "
          f"({t['frames_fitted']} frames; track {doc['track']}); no-match log-odds {doc['no_match']:+.2f}, "
          f"micro F1 {doc['meta']['validation']['micro_f1']:.3f} on seed {t['validation_seed']}")
    return 0
