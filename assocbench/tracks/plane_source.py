"""A lidar track's sequence (the planar and lines tracks': scans along a robot's path and what was
extracted from them) as a frame source, made once and kept in the shared sequence cache."""

from __future__ import annotations

from functools import partial
from importlib import import_module
from pathlib import Path
from typing import Any

from ..sim.cache import cached_sequence, load_fields, save_fields, spec_key
from ..sources.base import SimulatedSource, short_name


def maker_of(entry: str):
    """The function a ``module:function`` string names."""
    module, _, name = entry.partition(":")
    return getattr(import_module(module), name)


def lidar_frame(seq: Any, k: int) -> dict:
    """Frame ``k`` of a lidar sequence: the pose, the extracted features (``z``, ``R``), their
    labels, and which landmarks were detectable."""
    return {"pose": seq.poses[k], "z": seq.z[k], "R": seq.R[k], "labels": seq.labels[k], "visible": seq.visible[k]}


def load_lidar_sequence(folder: str, code: tuple[str, ...], maker: str, spec: Any,
                        cache_dir: Path | None = None, use_cache: bool = True) -> Any:
    """The sequence of ``spec`` from the cache under ``folder`` (key ``spec_key(spec, code)``), else
    made by ``maker`` and stored."""
    return cached_sequence(folder, spec_key(spec, code), lambda: maker_of(maker)(spec), save_fields, load_fields, cache_dir,
                           use_cache, suffix=".npz")


def lidar_source(track: str, spec: Any, code: tuple[str, ...], maker: str) -> SimulatedSource:
    """A lidar sequence as a frame source, cached under the track's name, keyed by its settings,
    scene files and ``code``'s folders."""
    return SimulatedSource(track, spec, short_name(spec.scene), spec.frames, partial(spec_key, code=code),
                           partial(load_lidar_sequence, track, code, maker), lidar_frame, cache_folder=track)
