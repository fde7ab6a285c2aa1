"""The sequence cache every track shares.

A track's simulated sequence (rendered frames and their features, depth images, lidar scans and
what was detected in them) is stored once under a key that hashes everything it depends on (the
spec, the scene's files, the sources that make it, the library versions: the track's ``key``),
in ``<cache>/<kind>/<key>.<suffix>``, so a sweep over many methods and seeds makes each sequence
once. A stored entry carries its key; reading checks it. An entry that cannot be read or is not
the sequence of its key (truncated, corrupted, copied over another) is discarded with one line on
stderr and made again; a cache folder that cannot be read or written is a one-line ``UserError``
naming ``ASSOCBENCH_CACHE``.

Tracks store their sequence their own way (``save`` and ``load``): the camera track as a compressed
NumPy archive of its arrays, the dense track as an uncompressed one whose frames are memory-mapped
and checked by their CRC-32 (``tracks/dense/sequence.py``), the lidar tracks (planar, lines: lists of small arrays
per frame) with ``save_pickled`` / ``load_pickled``, which is safe here because the cache is the
user's own folder and an entry is only read back under the key this code computed.
"""

from __future__ import annotations

import hashlib
import json
import pickle
import struct
import sys
import zipfile
import zlib
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import TypeVar

import mujoco

from .._runtime import cache_root
from ..atomic import CACHE, atomic_path
from ..errors import UserError
from ..fingerprint import sources_digest
from .scene import scene_digest

T = TypeVar("T")


class Unusable(Exception):
    """A cache entry that reads, but is not the sequence its key names."""


# what reading a damaged entry can raise: a truncated or flipped zip (BadZipFile, EOFError,
# zlib.error, OSError), a damaged array header (ValueError, SyntaxError, MemoryError for an absurd
# shape), a missing member (KeyError), a damaged pickle (UnpicklingError, AttributeError, ...)
DAMAGED = (Unusable, OSError, EOFError, ValueError, KeyError, IndexError, TypeError, SyntaxError, MemoryError,
           NotImplementedError, RuntimeError, AttributeError, ImportError, zipfile.BadZipFile, zlib.error,
           struct.error, pickle.UnpicklingError)


def cached_sequence(kind: str, key: str, make: Callable[[], T], save: Callable[[T, Path, str], None],
                    load: Callable[[Path, str], T], cache_dir: Path | None = None, use_cache: bool = True,
                    suffix: str = ".npz", what: str = "sequence") -> T:
    """The sequence stored under ``key`` in ``<cache_dir>/<kind>/`` when present and sound, else
    ``make()``, stored there (atomically) before it is returned. ``save(seq, path, key)`` writes
    an entry with its key inside; ``load(path, key)`` reads one back, raising ``Unusable`` (or any
    of ``DAMAGED``) when it is not that sequence."""
    path = Path(cache_dir or cache_root()) / kind / f"{key}{suffix}"
    if use_cache:
        seq = _read(path, key, load, what)
        if seq is not None:
            return seq
    seq = make()
    if use_cache:
        with atomic_path(path, suffix=suffix, role=CACHE) as tmp:
            save(seq, tmp, key)
    return seq


def _read(path: Path, key: str, load: Callable[[Path, str], T], what: str) -> T | None:
    """The entry at ``path`` if it is there and sound; a damaged one is removed with one line."""
    try:
        if not path.is_file():
            return None
        return load(path, key)
    except PermissionError as exc:  # a cache we may not read is a setting to fix, not damage
        # name the file or folder refused (an entry's chmod 000 left its folder readable: naming
        # only the cache folder sent the user looking at the wrong permissions)
        denied = exc.filename or path
        raise UserError(f"cannot read {CACHE.what} {path.parent.parent} ({denied}: {exc.strerror}); "
                        f"make it readable or delete it, or {CACHE.fix()}") from None
    except DAMAGED as exc:
        reason = str(exc) if isinstance(exc, Unusable) else f"{type(exc).__name__}: {exc}".splitlines()[0][:120]
    try:
        path.unlink(missing_ok=True)
    except OSError as exc:   # a folder we may not change would refuse the fresh entry too: say so before rendering
        raise UserError(f"cached {what} {path} is unusable ({reason}) and cannot be removed: {exc.strerror}; "
                        f"{CACHE.fix()}") from None
    print(f"assocbench: cached {what} {path} is unusable ({reason}); discarding it and rendering again",
          file=sys.stderr)
    return None


def spec_key(spec: object, code: tuple[str, ...], fmt: int = 1) -> str:
    """A cache key (20 hex digits) for a dataclass ``spec`` whose ``scene`` names an MJCF: its
    settings, the scene's files (``scene_digest``), the content of a file its path is read from
    (``spec.path_digest()`` where it has one: a robot's waypoint file, whose name alone is in
    the settings), the sources under ``code`` (folders of the package: ``("sim", "models",
    "tracks/planar")``), the entry format and MuJoCo's version."""
    payload = {"spec": asdict(spec), "scene": scene_digest(spec.scene), "code": sources_digest(*code), "format": fmt,
               "mujoco": mujoco.__version__}
    path_file = spec.path_digest() if callable(getattr(spec, "path_digest", None)) else None
    if path_file is not None:   # only then: the keys of every other path stay what they were
        payload["path_file"] = path_file
    return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:20]


def save_pickled(seq: object, path: Path, key: str) -> None:
    """Write ``seq`` with its ``key`` (a lidar track's sequence: lists of small per-frame arrays)."""
    with open(path, "wb") as fh:
        pickle.dump({"key": key, "sequence": seq}, fh, protocol=pickle.HIGHEST_PROTOCOL)


def load_pickled(path: Path, key: str) -> object:
    """The sequence ``save_pickled`` wrote under ``key``; ``Unusable`` for another key."""
    with open(path, "rb") as fh:
        entry = pickle.load(fh)   # noqa: S301 - the user's own cache, read only under the key we computed
    if not isinstance(entry, dict) or entry.get("key") != key:
        raise Unusable("it was stored under another key")
    return entry["sequence"]
