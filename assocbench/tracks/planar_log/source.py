"""A recorded log as a frame source: parsed once per process when needed, its reference solution
from the sequence cache (or computed and stored), neither pickled to a worker."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

from ...sources.base import digest, file_digest, short_name
from ...sources.range_bearing_log import LogError, RangeBearingLog, read_log
from .reference import CACHE_FOLDER, reference_solution
from .sequence import LogSequence, frame_poses, make_log_sequence
from .settings import LogConfig

_LOGS: dict[tuple[str, str], RangeBearingLog] = {}   # (path, file digest) -> the parsed log, once per process


def parsed_log(path: Path, file_key: str) -> RangeBearingLog:
    """The log at ``path`` whose bytes have the digest ``file_key``, parsed once in this process."""
    key = (str(path), file_key)
    if key not in _LOGS:
        _LOGS[key] = read_log(path)
    return _LOGS[key]


class PlanarLogSource:
    """A log's frames (``sequence.LogSequence``): ``key`` = the file's digest and the settings."""

    track = "planar_log"
    cache_folder = CACHE_FOLDER

    def __init__(self, path: Path, frames: int | None, cfg: LogConfig, name: str | None = None) -> None:
        self.path, self.cfg, self.frames_asked = Path(path), cfg, frames
        self.name = name or short_name(path)
        self.file_key = file_digest(self.path)
        self.key = digest({"log": self.file_key, "log_settings": asdict(cfg), "frames": frames})
        self._length: int | None = None
        self._sequence: LogSequence | None = None

    @property
    def log(self) -> RangeBearingLog:
        """The parsed log (a one-line ``LogError`` for a bad one, or one without sightings)."""
        log = parsed_log(self.path, self.file_key)
        if not len(log.sighting_ref):   # odometry alone (a consistency study reads such logs; a run cannot)
            raise LogError(f"{self.path}: the log holds no LANDMARK line, so a run has nothing to associate; "
                           "add its sightings (the format: docs/tracks/planar_log.md)")
        return log

    def __len__(self) -> int:
        if self._length is None:
            self._length = len(frame_poses(self.log, self.frames_asked))
        return self._length

    def load(self, cache_dir: Path | None = None, use_cache: bool = True) -> LogSequence:
        """The sequence: the log with its reference solution (from ``cache_dir``'s sequence cache)."""
        if self._sequence is None:
            reference = reference_solution(self.log, cache_dir, use_cache)
            self._sequence = make_log_sequence(self.log, reference, self.cfg, self.frames_asked)
        return self._sequence

    @property
    def sequence(self) -> LogSequence:
        """The loaded sequence (``load()`` with the default cache)."""
        return self.load()

    def __getitem__(self, k: int) -> dict:
        seq = self.sequence
        if not 0 <= k < len(seq):
            raise IndexError(f"frame {k} of a {len(seq)}-frame log")
        return {"pose": seq.poses[k], "z": seq.z[k], "R": seq.R[k], "labels": seq.labels[k], "visible": seq.visible[k]}

    def __getstate__(self) -> dict:
        return self.__dict__ | {"_sequence": None}   # made again where it is used; the log is parsed there once

    def __repr__(self) -> str:
        return f"PlanarLogSource({self.name}, {len(self)} frames)"
