"""Read an export back: ``(Problem, FrameTruth)`` with its labels, a batch of rows at a time, so
a dataset larger than memory streams (only one batch's arrays are ever held)."""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import yaml

from ..association.problem import Problem
from ..association.truth import FrameTruth
from ..errors import UserError
from ..validation import BoundedLoader, brief
from .schema import (
    ARRAYS,
    CARD_FILE,
    LABELS,
    PROBLEMS_FILE,
    READABLE_VERSIONS,
    SCHEMA_VERSION,
    SIZES,
    columns_of,
    pyarrow,
    row_problem,
)


@dataclass(frozen=True)
class LabelledProblem:
    """One frame of an export: its problem, its truth and what made it."""

    problem: Problem
    truth: FrameTruth
    track: str
    scene: str
    difficulty: str
    seed: int
    frame: int


def read_card(folder: str | Path) -> dict:
    """The dataset card (``card.yaml``) of an export folder, its schema version checked."""
    path = Path(folder) / CARD_FILE
    if not (Path(folder) / PROBLEMS_FILE).is_file() or not path.is_file():
        raise UserError(f"{folder} is not an assocbench export ({PROBLEMS_FILE} and {CARD_FILE} expected); "
                        "make one with `assocbench export --suite S --out DIR`")
    try:
        card = yaml.load(path.read_text(), Loader=BoundedLoader)  # noqa: S506 - a SafeLoader, aliases bounded
    except yaml.YAMLError as exc:
        raise UserError(f"{path} is not a readable dataset card ({_first_line(exc)}): export the data again") from exc
    version = card.get("schema_version") if isinstance(card, dict) else None
    if version not in READABLE_VERSIONS:
        raise UserError(f"{path} has schema version {brief(version)}, this assocbench reads versions "
                        f"{', '.join(map(str, READABLE_VERSIONS))}, writes {SCHEMA_VERSION}: "
                        "export the data again with this version")
    return card


def read_problems(folder: str | Path, batch_size: int = 64) -> Iterator[list[LabelledProblem]]:
    """Batches of up to ``batch_size`` frames of the export in ``folder``, in the order written."""
    parquet = _open_table(folder)
    for batch in parquet.iter_batches(batch_size=batch_size):
        yield list(_batch_problems(batch))


def _batch_problems(batch) -> Iterator[LabelledProblem]:
    present = set(batch.schema.names)   # a version 1 table has no appearance columns
    scalars = {name: batch.column(name).to_pylist() for name, _ in LABELS + SIZES if name in present}
    lists = {}
    for name, _ in ARRAYS:
        if name not in present:
            continue
        col = batch.column(name)
        # a sliced list column keeps offsets into its whole values buffer: slice that buffer by them
        lists[name] = (col.values.to_numpy(zero_copy_only=False), col.offsets.to_numpy())
    for k in range(batch.num_rows):
        row = {name: values[k] for name, values in scalars.items()}
        for name, (values, offsets) in lists.items():
            row[name] = values[offsets[k]:offsets[k + 1]]
        problem, truth = row_problem(row)
        try:
            truth.validate(problem)
        except ValueError as exc:
            raise UserError(f"frame {row['frame']} of {row['scene']} seed {row['seed']} in the export is invalid: {exc}; "
                            "export the data again") from None
        yield LabelledProblem(problem, truth, row["track"], row["scene"], row["difficulty"], int(row["seed"]),
                              int(row["frame"]))


def count_frames(folder: str | Path) -> int:
    """Number of frames (rows) in the export, from the Parquet footer (nothing else is read)."""
    return int(_open_table(folder).metadata.num_rows)


def _open_table(folder: str | Path):
    """The export's Parquet table, opened after its card is checked; a damaged or foreign table, or
    one whose bytes are not those the card's SHA-256 records, is a one-line error (pyarrow's own
    would be a traceback)."""
    card = read_card(folder)
    version = card["schema_version"]
    path = Path(folder) / PROBLEMS_FILE
    pa = pyarrow()
    try:
        parquet = pa.parquet.ParquetFile(path)
    except (pa.ArrowException, OSError) as exc:
        raise UserError(f"{path} is not a readable Parquet table ({_first_line(exc)}): export the data again") from exc
    missing = [name for name in columns_of(version) if name not in parquet.schema_arrow.names]
    if missing:
        raise UserError(f"{path} lacks the columns {', '.join(missing)} of an assocbench export: export the data again")
    _check_digest(path, card)
    return parquet


def _check_digest(path: Path, card: dict) -> None:
    """Refuse a table whose SHA-256 is not the one the card records: a table changed after export
    (truth labels edited, rows swapped) would train and score silently."""
    recorded = ((card.get("files") or {}).get(PROBLEMS_FILE) or {}).get("sha256")
    if not isinstance(recorded, str):
        raise UserError(f"{path.parent / CARD_FILE} records no sha256 of {PROBLEMS_FILE}: export the data again")
    with path.open("rb") as f:
        digest = hashlib.file_digest(f, "sha256").hexdigest()
    if digest != recorded:
        raise UserError(f"{path} is not the table its card records (sha256 {digest[:16]}, the card's {recorded[:16]}): "
                        "it was changed after export; export the data again")


def _first_line(exc: Exception) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


__all__ = ["LabelledProblem", "read_card", "read_problems", "count_frames"]
