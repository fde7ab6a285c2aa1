"""The frame source: the one interface between where frames come from and the track reading them, in
the spirit of kiss-icp's dataset classes:

* ``len(source)``: the frames a run takes;
* ``source[k]``: frame ``k``, read when asked for (a log parsed once, a simulated sequence made or
  read from the cache on first access);
* ``source.key``: a digest of every input the frames depend on (files, settings, code, library
  versions); caches and stored runs are reused only under the same key;
* ``source.name``: a short name for scenarios and titles, never a machine path;
* ``source.track``: the registered track that reads it.

A source is cheap to pickle (it travels to workers): what it loads is dropped when pickled and
loaded again where used.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

KEY_DIGITS = 20   # hex digits of a key: 80 bits, no accidental collision among a user's runs


@runtime_checkable
class FrameSource(Protocol):
    """What a track reads its frames from (module docstring)."""

    track: str
    name: str

    @property
    def key(self) -> str:
        """Digest of every input the frames depend on."""

    def __len__(self) -> int:
        """The number of frames."""

    def __getitem__(self, k: int) -> Any:
        """Frame ``k``, read when asked for."""


def digest(payload: Any) -> str:
    """SHA-256 (``KEY_DIGITS`` hex digits) of a JSON-able ``payload`` (keys sorted, other values by
    ``str``)."""
    text = json.dumps(payload, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:KEY_DIGITS]


def file_digest(path: str | Path) -> str:
    """SHA-256 (16 hex digits) of a file's bytes: a recorded log, a waypoint file, a mesh."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:16]


def short_name(scene: str | Path) -> str:
    """A source's short name: the file's stem (``/data/my room.xml`` -> ``my room``), never a
    machine path."""
    return Path(str(scene)).stem or str(scene)


class SimulatedSource:
    """A track's simulated sequence as a frame source: ``spec`` determines it;
    ``load(spec, cache_dir, use_cache)`` makes or reads it on first access; ``key(spec)`` is its
    content key; ``frame(sequence, k)`` its frame ``k``. Pickling keeps only what makes it
    (module-level callables or partials)."""

    def __init__(self, track: str, spec: Any, name: str, frames: int, key: Callable[[Any], str],
                 load: Callable[..., Any], frame: Callable[[Any, int], Any], cache_folder: str | None = None) -> None:
        self.track, self.spec, self.name, self.frames = track, spec, name, int(frames)
        self.cache_folder = cache_folder   # its subfolder of the sequence cache, checked before a run
        self._key_of, self._load, self._frame = key, load, frame
        self._key: str | None = None
        self._sequence: Any = None

    @property
    def key(self) -> str:
        if self._key is None:
            self._key = self._key_of(self.spec)
        return self._key

    def load(self, cache_dir: Path | None = None, use_cache: bool = True) -> Any:
        """The sequence (made or read from the cache once, then kept)."""
        if self._sequence is None:
            self._sequence = self._load(self.spec, cache_dir, use_cache)
        return self._sequence

    @property
    def sequence(self) -> Any:
        """The loaded sequence (``load()`` with the default cache)."""
        return self.load()

    def __len__(self) -> int:
        return self.frames

    def __getitem__(self, k: int) -> Any:
        if not 0 <= k < self.frames:
            raise IndexError(f"frame {k} of a {self.frames}-frame source")
        return self._frame(self.load(), k)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_sequence"] = None   # loaded again where it is used
        return state

    def __repr__(self) -> str:
        return f"SimulatedSource({self.track}, {self.name}, {self.frames} frames)"
