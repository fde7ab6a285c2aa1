"""The dataset's one table: a row per frame, the ``Problem`` and ``FrameTruth`` arrays flattened
in C order beside their sizes (``m``, ``n``, ``d``) and what made them (track, scene, difficulty,
seed, frame). Parquet through pyarrow (an optional package: ``pip install assocbench[learn]``)."""

from __future__ import annotations

import numpy as np

from ..association.problem import Problem
from ..association.truth import FrameTruth
from ..errors import UserError

SCHEMA_VERSION = 2        # 2 added the optional appearance columns (APPEARANCE); version 1 is still read
READABLE_VERSIONS = (1, 2)
PROBLEMS_FILE = "problems.parquet"
CARD_FILE = "card.yaml"
ROW_GROUP = 16   # frames per row group: the unit a reader loads at once (a 80-landmark camera frame is ~0.2 MB)
# label columns, then sizes, then the Problem's arrays, then the truth's
LABELS = (("track", "string"), ("scene", "string"), ("difficulty", "string"), ("seed", "int64"),
          ("frame", "int32"))
SIZES = (("m", "int32"), ("n", "int32"), ("d", "int32"), ("volume", "float64"), ("descriptor_length", "int32"))
# descriptors as float32: exact for SIFT's bytes and for their means, half the size of float64
ARRAYS = (("z", "float64"), ("R", "float64"), ("zhat", "float64"), ("P", "float64"), ("landmark_ids", "int64"),
          ("angular", "int32"), ("descriptors", "float32"), ("landmark_descriptors", "float32"),
          ("feature_labels", "int64"), ("association", "int64"), ("visible", "bool"))
APPEARANCE = ("descriptor_length", "descriptors", "landmark_descriptors")   # not in a version 1 table


def pyarrow():
    """The ``pyarrow`` module, or a one-line error saying how to install it."""
    try:
        import pyarrow as pa
        import pyarrow.parquet  # noqa: F401 - the submodule the writer and reader use
    except ImportError:
        raise UserError("the dataset needs pyarrow: pip install 'assocbench[learn]'") from None
    return pa


def arrow_schema():
    """The table's schema (lists of numbers for the arrays)."""
    pa = pyarrow()
    scalar = [(name, pa.type_for_alias(kind)) for name, kind in LABELS + SIZES]
    lists = [(name, pa.list_(pa.type_for_alias(kind))) for name, kind in ARRAYS]
    return pa.schema([pa.field(name, kind, nullable=False) for name, kind in scalar + lists])


def columns_of(version: int) -> list[str]:
    """The columns a table of schema ``version`` has."""
    names = [name for name, _ in LABELS + SIZES + ARRAYS]
    return names if version >= 2 else [n for n in names if n not in APPEARANCE]


def frame_row(labels: dict, problem: Problem, truth: FrameTruth) -> dict:
    """One row: ``labels`` (track, scene, difficulty, seed, frame) and the flattened arrays; a problem
    without descriptors has ``descriptor_length`` 0 and empty descriptor lists."""
    row = {name: labels[name] for name, _ in LABELS}
    has = problem.descriptors is not None
    row.update(m=problem.m, n=problem.n, d=problem.d, volume=float(problem.volume),
               descriptor_length=problem.descriptors.shape[1] if has else 0)
    for name in ("z", "R", "zhat", "P", "landmark_ids"):
        row[name] = np.asarray(getattr(problem, name)).ravel()
    for name in ("descriptors", "landmark_descriptors"):
        row[name] = np.asarray(getattr(problem, name), np.float32).ravel() if has else np.zeros(0, np.float32)
    row["angular"] = np.asarray(problem.angular, dtype=np.int32)
    row["feature_labels"] = np.asarray(truth.feature_labels, dtype=np.int64).ravel()
    row["association"] = np.asarray(truth.association, dtype=np.int64).ravel()
    row["visible"] = np.asarray(truth.visible, dtype=bool).ravel()
    return row


def row_problem(row: dict) -> tuple[Problem, FrameTruth]:
    """The ``Problem`` and ``FrameTruth`` of one row (its arrays reshaped by ``m``, ``n``, ``d`` and
    ``descriptor_length``, absent or 0: no descriptors)."""
    m, n, d, length = int(row["m"]), int(row["n"]), int(row["d"]), int(row.get("descriptor_length", 0))
    arr = lambda name, kind=np.float64: np.asarray(row[name], dtype=kind)  # noqa: E731
    appearance = {name: arr(name, np.float32).reshape(rows, length) for name, rows in
                  (("descriptors", m), ("landmark_descriptors", n))} if length else {}
    problem = Problem(arr("z").reshape(m, d), arr("R").reshape(m, d, d), arr("zhat").reshape(n, d),
                      arr("P").reshape(n * d, n * d), arr("landmark_ids", np.int64), float(row["volume"]),
                      tuple(int(a) for a in row["angular"]), **appearance)
    truth = FrameTruth(arr("feature_labels", np.int64), arr("association", np.int64), arr("visible", bool))
    return problem, truth
