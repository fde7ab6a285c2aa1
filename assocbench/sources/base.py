"""The frame source: the one interface between where frames come from and the track that reads them.

A frame source is a sequence of frames with a content key, in the spirit of kiss-icp's dataset
classes (``__len__`` / ``__getitem__``, made by a factory: here the track's ``source`` hook):

* ``len(source)``: how many frames a run takes;
* ``source[k]``: frame ``k``, read when it is asked for (a log parsed once, then indexed; a simulated
  sequence made, or read from the sequence cache, on first access), never a list built up front;
* ``source.key``: a digest of every input the frames depend on (the files read: an MJCF with its
  includes, meshes and textures, a waypoint file, a log file; the settings; the code that makes the
  frames; the library versions that change them). The sequence cache and a stored run are reused
  only under the same key, so an edited log, mesh or texture is never silently reused;
* ``source.name``: a short name for scenarios and titles (``park``, ``victoria_park``, a log file's
  stem), never a machine path;
* ``source.track``: the name of the registered track that reads it.

A source is picklable and cheap to pickle (it travels to worker processes, which read its frames
there): whatever it loads is dropped when it is pickled and loaded again where it is used.
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
    """SHA-256 (``KEY_DIGITS`` hex digits) of a JSON-able ``payload`` (keys sorted; other values by
    their ``str``): the key of a source from its settings and the digests of its inputs."""
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
    """A source's short name from a shipped name or a file path: the file's stem (``/data/my room.xml``
    -> ``my room``), so a scenario never carries a machine path."""
    return Path(str(scene)).stem or str(scene)


class SimulatedSource:
    """A track's simulated sequence as a frame source.

    ``spec`` (picklable) determines the sequence; ``load(spec, cache_dir, use_cache)`` makes it or reads
    it from the sequence cache, on first access; ``key(spec)`` is its content key (the cache's key);
    ``frame(sequence, k)`` is frame ``k`` of a loaded sequence. The loaded sequence stays in this
    process: pickling the source keeps only what makes it (the callables must be module-level
    functions or partials of them)."""

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
