"""Read an export back: ``(Problem, FrameTruth)`` with its labels, a batch of rows at a time, so
a dataset larger than memory streams (only one batch's arrays are ever held)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import yaml

from ..association.problem import Problem
from ..association.truth import FrameTruth
from ..errors import UserError
from .schema import ARRAYS, CARD_FILE, LABELS, PROBLEMS_FILE, SCHEMA_VERSION, SIZES, pyarrow, row_problem


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
    card = yaml.safe_load(path.read_text())
    version = card.get("schema_version") if isinstance(card, dict) else None
    if version != SCHEMA_VERSION:
        raise UserError(f"{path} has schema version {version!r}, this assocbench reads version {SCHEMA_VERSION}: "
                        "export the data again with this version")
    return card


def read_problems(folder: str | Path, batch_size: int = 64) -> Iterator[list[LabelledProblem]]:
    """Batches of up to ``batch_size`` frames of the export in ``folder``, in the order written."""
    read_card(folder)
    pa = pyarrow()
    parquet = pa.parquet.ParquetFile(Path(folder) / PROBLEMS_FILE)
    for batch in parquet.iter_batches(batch_size=batch_size):
        yield list(_batch_problems(batch))


def _batch_problems(batch) -> Iterator[LabelledProblem]:
    scalars = {name: batch.column(name).to_pylist() for name, _ in LABELS + SIZES}
    lists = {}
    for name, _ in ARRAYS:
        col = batch.column(name)
        # a sliced list column keeps offsets into its whole values buffer: slice that buffer by them
        lists[name] = (col.values.to_numpy(zero_copy_only=False), col.offsets.to_numpy())
    for k in range(batch.num_rows):
        row = {name: values[k] for name, values in scalars.items()}
        for name, (values, offsets) in lists.items():
            row[name] = values[offsets[k]:offsets[k + 1]]
        problem, truth = row_problem(row)
        yield LabelledProblem(problem, truth, row["track"], row["scene"], row["difficulty"], int(row["seed"]),
                              int(row["frame"]))


def count_frames(folder: str | Path) -> int:
    """Number of frames (rows) in the export, from the Parquet footer (nothing else is read)."""
    read_card(folder)
    return int(pyarrow().parquet.ParquetFile(Path(folder) / PROBLEMS_FILE).metadata.num_rows)


__all__ = ["LabelledProblem", "read_card", "read_problems", "count_frames"]
