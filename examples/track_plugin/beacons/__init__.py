"""A track of recorded 2-D landmark sightings: each frame of a log holds the candidates a user's
own filter predicted (position and covariance) and the measurements it made (position, noise and
the landmark a reference labelling gave them, -1 for none). Rows are whitespace-separated:

    L <frame> <landmark id> <x> <y> <sxx> <sxy> <syy>      a predicted candidate (m, m²)
    Z <frame> <reference id> <x> <y> <sxx> <sxy> <syy>     a measurement and its noise
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from assocbench import Problem
from assocbench.association.truth import FrameTruth
from assocbench.errors import UserError
from assocbench.settings import Schema, Section
from assocbench.sources.base import digest, file_digest, short_name
from assocbench.tracks.base import Columns, FeatureTrack, Metric, SuiteFile
from assocbench.tracks.capabilities import EnvSlots, gym_envs_of
from assocbench.validation import in_range, validate_fields

HERE = Path(__file__).parent


@dataclass(frozen=True)
class LogSettings:
    """Section ``log``.

    area: the measurement domain's area (m²): the surprisal of a landmark left unassociated.
    noise_scale: every covariance of the log is multiplied by this (a difficulty knob).
    """

    area: float = field(default=100.0, metadata=in_range(0, None, lo_open=True))
    noise_scale: float = field(default=1.0, metadata=in_range(0, 100, lo_open=True))

    def __post_init__(self) -> None:
        validate_fields(self, "log")


def read_log(path: Path) -> dict[int, dict[str, list]]:
    """Frame -> {"L": rows, "Z": rows}; a bad line is one error naming the file and the line."""
    frames: dict[int, dict[str, list]] = {}
    for number, line in enumerate(path.read_text().splitlines(), 1):
        parts = line.split("#")[0].split()
        if not parts:
            continue
        try:
            kind, frame, ident, *numbers = parts[0], int(parts[1]), int(parts[2]), *map(float, parts[3:])
            assert kind in ("L", "Z") and len(numbers) == 5 and np.isfinite(numbers).all()
        except (ValueError, IndexError, AssertionError):
            raise UserError(f"{path} line {number}: expected 'L|Z frame id x y sxx sxy syy', got {line!r}") from None
        frames.setdefault(frame, {"L": [], "Z": []})[kind].append((ident, *numbers))
    if not frames:
        raise UserError(f"{path} holds no L or Z line: give a beacons log")
    return frames


class LogSource:
    """A recorded log as a frame source: frames are parsed when first read."""

    track = "beacons"

    def __init__(self, path: Path, frames: int | None, settings: LogSettings) -> None:
        self.path, self.settings, self.name = path, settings, short_name(path)
        self._frames = None
        self._length = min(frames or len(self.frames()), len(self.frames()))
        self.key = digest([file_digest(path), vars(settings)])

    def frames(self) -> list:
        if self._frames is None:
            parsed = read_log(self.path)
            self._frames = [parsed[k] for k in sorted(parsed)]
        return self._frames

    def __len__(self) -> int:
        return self._length

    def __getitem__(self, k: int) -> dict:
        return self.frames()[k]

    def __getstate__(self) -> dict:
        return self.__dict__ | {"_frames": None}


def arrays(rows: list, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ids (k,), positions (k, 2) and covariances (k, 2, 2) of a frame's rows."""
    a = np.array(rows, float).reshape(-1, 6)
    cov = np.stack([a[:, 3], a[:, 4], a[:, 4], a[:, 5]], axis=1).reshape(-1, 2, 2)
    return a[:, 0].astype(np.int64), a[:, 1:3], scale * cov


class BeaconsTrack(FeatureTrack):
    """Recorded 2-D landmark sightings with a reference labelling, from a log file."""

    name = "beacons"
    summary = "recorded 2-D landmark sightings and their predicted candidates, from a log file"

    def settings(self) -> Schema:
        return Schema((), {"log": Section(LogSettings)})

    def source(self, settings) -> LogSource:
        path = HERE / "sample.log" if settings.scene in (None, "sample") else Path(settings.scene)
        if not path.is_file():
            raise UserError(f"beacons log {settings.scene!r} not found: give 'sample' or a log file")
        return LogSource(path, settings.frames, settings.log)

    def problem(self, source: LogSource, k: int, run) -> tuple[Problem, FrameTruth]:
        frame, scale = source[k], source.settings.noise_scale
        ids, zhat, P_blocks = arrays(frame["L"], scale)
        refs, z, R = arrays(frame["Z"], scale)
        n = len(ids)
        P = np.zeros((2 * n, 2 * n))
        for j in range(n):
            P[2 * j:2 * j + 2, 2 * j:2 * j + 2] = P_blocks[j]
        problem = Problem(z=z, R=R, zhat=zhat, P=P, landmark_ids=ids, volume=source.settings.area)
        association = np.array([np.flatnonzero(refs == i)[0] if (refs == i).any() else -1 for i in ids], np.int64)
        labels = np.where(np.isin(refs, ids), refs, -1)
        return problem, FrameTruth(labels, association, association >= 0)

    def columns(self, loop: bool) -> Columns:
        """The shared columns, ranked by the share of frames associated exactly."""
        return replace(super().columns(loop), primary=Metric("perfect", True, "share of frames"))

    def suites(self) -> dict[str, SuiteFile]:
        return {"beacons_ci": SuiteFile(HERE / "beacons_ci.yaml", ci=True)}

    def scenes(self) -> dict[str, str]:
        return {"sample": "a 12-frame log shipped with the plugin"}

    def gym_envs(self):
        return gym_envs_of(self.scenes(), ("open",))

    def env_slots(self, run) -> EnvSlots:
        frames = [run.source[k] for k in range(len(run.source))]
        return EnvSlots(max(len(f["L"]) for f in frames), max(len(f["Z"]) for f in frames))
