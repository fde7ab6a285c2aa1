"""Write labelled problems as the dataset's Parquet table, byte for byte reproducibly: fixed-size
row groups (``ROW_GROUP``), pinned writer options, nothing time- or host-dependent in the file or
card; both land only when every row is written (``atomic_paths``)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import yaml

from ..association.problem import Problem
from ..association.truth import FrameTruth
from ..atomic import atomic_paths
from .schema import (
    ARRAYS,
    CARD_FILE,
    LABELS,
    PROBLEMS_FILE,
    ROW_GROUP,
    SCHEMA_VERSION,
    SIZES,
    arrow_schema,
    frame_row,
    pyarrow,
)

WRITER_OPTIONS = {"compression": "zstd", "compression_level": 3, "use_dictionary": False,
                  "write_statistics": True, "version": "2.6", "data_page_version": "1.0"}


class DatasetWriter:
    """``with DatasetWriter(folder, card) as w: w.add(labels, problem, truth)``: the table and its
    card (``card`` completed with the schema, the sizes and the table's SHA-256) in ``folder``."""

    def __init__(self, folder: Path, card: dict) -> None:
        self.folder, self.card = Path(folder), dict(card)
        self.rows: list[dict] = []
        self.frames: dict[str, int] = {}
        self._group = atomic_paths([self.folder / PROBLEMS_FILE, self.folder / CARD_FILE])

    def __enter__(self) -> DatasetWriter:
        self._table_tmp, self._card_tmp = self._group.__enter__()
        self._writer = pyarrow().parquet.ParquetWriter(self._table_tmp, arrow_schema(), **WRITER_OPTIONS)
        return self

    def add(self, labels: dict, problem: Problem, truth: FrameTruth) -> None:
        """Append one frame (``labels``: track, scene, difficulty, seed, frame)."""
        self.rows.append(frame_row(labels, problem, truth))
        self.frames[labels["track"]] = self.frames.get(labels["track"], 0) + 1
        if len(self.rows) == ROW_GROUP:
            self._flush()

    def _flush(self) -> None:
        pa = pyarrow()
        columns = {name: [r[name] for r in self.rows] for name, _ in LABELS + SIZES + ARRAYS}
        self._writer.write_table(pa.Table.from_pydict(columns, schema=arrow_schema()), row_group_size=ROW_GROUP)
        self.rows = []

    def __exit__(self, kind, exc, tb) -> bool:
        try:
            if self.rows and kind is None:
                self._flush()
            self._writer.close()
            if kind is None:
                self._card_tmp.write_text(yaml.safe_dump(self._complete_card(), sort_keys=False, width=100))
        except BaseException as error:  # noqa: BLE001 - the group must drop its temporary files
            self._group.__exit__(type(error), error, error.__traceback__)
            raise
        return bool(self._group.__exit__(kind, exc, tb))

    def _complete_card(self) -> dict:
        data = self._table_tmp.read_bytes()
        sizes = {"frames": sum(self.frames.values()), "frames_per_track": dict(self.frames),
                 "bytes": len(data), "row_group_frames": ROW_GROUP}
        return {"schema_version": SCHEMA_VERSION, **self.card, "sizes": sizes,
                "files": {PROBLEMS_FILE: {"sha256": hashlib.sha256(data).hexdigest(),
                                          "writer": dict(WRITER_OPTIONS)}},
                "schema": schema_description()}


COLUMN_MEANING = {
    "track": "the track that made the problem (camera, planar, lines, photos)",
    "scene": "scene name or MJCF path", "difficulty": "the suite's difficulty name",
    "seed": "the run's seed (sequence and belief)", "frame": "frame index in the sequence, from 0",
    "m": "number of measurements", "n": "number of candidate landmarks", "d": "measurement dimension",
    "volume": "|Y|, the measure of the measurement domain (camera: image area in px^2)",
    "z": "(m, d) measurements, C order (camera: px; planar: m, rad; lines: rad, m)",
    "R": "(m, d, d) measurement noise covariances", "zhat": "(n, d) predicted measurements",
    "P": "(n d, n d) joint covariance of the predictions, cross terms kept",
    "landmark_ids": "(n,) map ids of the candidates", "angular": "measurement dims that wrap (radians)",
    "descriptor_length": "D, the length of a descriptor; 0: the problem has no descriptors (a geometric track)",
    "descriptors": "(m, D) appearance of each measurement (photos: its SIFT descriptor), C order, float32",
    "landmark_descriptors": "(n, D) appearance of each candidate (photos: the mean SIFT descriptor of the keypoints "
                            "that built it in the other images), float32",
    "feature_labels": "(m,) truth (a recorded track: its reference): map id imaged by each measurement, -1 for "
                      "clutter and look-alikes",
    "association": "(n,) truth (or reference): feature paired with each candidate, -1 for none",
    "visible": "(n,) truth (or reference): whether each candidate is really visible",
}


def schema_description() -> list[dict]:
    """Each column with its Arrow type and meaning (the card's ``schema``)."""
    return [{"name": f.name, "type": str(f.type), "meaning": COLUMN_MEANING[f.name]} for f in arrow_schema()]
