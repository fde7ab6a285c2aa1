"""The benchmark's labelled association problems as a dataset: one Parquet row per frame
(``schema``), written by ``assocbench export`` (``harness/export.py``) and read back as
``(Problem, FrameTruth)`` pairs, batch by batch (``reader``)."""

from .reader import LabelledProblem, read_card, read_problems

__all__ = ["LabelledProblem", "read_problems", "read_card"]
