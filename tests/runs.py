"""Runs over sequences a test already holds: the ``RunSpec`` and frame source the harness's frame
loops take (``loop_records``, ``ClosedLoop``, ``Problems``), built from a sequence in memory and the
typed sections a test names, every other setting at its track's default."""

from __future__ import annotations

import math

from assocbench.harness.config import RunSpec, defaults, run_schema
from assocbench.settings import Settings
from assocbench.tracks.registry import get_track


class Loaded:
    """A sequence already in memory as a frame source."""

    def __init__(self, seq, track: str | None = None) -> None:
        self.sequence, self.track = seq, track or seq.track
        self.name, self.key = str(getattr(seq, "scene", "memory")), f"memory-{id(seq)}"

    def load(self, cache_dir=None, use_cache: bool = True):
        return self.sequence

    def __len__(self) -> int:
        return len(self.sequence)

    def __getitem__(self, k: int):
        return k


def run_on(seq, method: str = "oracle", params: dict | None = None, seed: int = 0, loop: bool = True,
           time_limit_s: float = math.inf, **sections) -> tuple[Loaded, RunSpec]:
    """(source, run) of ``method`` on the in-memory ``seq`` with the typed ``sections`` given
    (``belief=BeliefConfig(...)``, ``estimator=EstimatorConfig(...)``), the rest the track's defaults."""
    source = Loaded(seq)
    track = get_track(source.track)
    values = dict(run_schema(track).build(defaults(track)))
    values |= {"method": method, "params": dict(params or {}), "seed": seed, "loop": loop,
               "time_limit_s": time_limit_s} | sections
    return source, RunSpec(track.name, source, Settings(values), method, dict(params or {}))
