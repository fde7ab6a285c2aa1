"""The sequence cache every track shares.

A track's simulated sequence is stored once under a key hashing everything it depends on (spec,
scene files, the sources that make it, library versions), in ``<cache>/<kind>/<key>.<suffix>``, so a
sweep makes each sequence once. An entry carries its key and reading checks it; an unreadable entry
or one not of its key is discarded with one line on stderr and made again; an unusable cache folder
is a one-line ``UserError`` naming ``ASSOCBENCH_CACHE``. Each track stores its own way (``save``,
``load``): NumPy archives (the dense track's uncompressed and memory-mapped, the lidar tracks' via
``save_fields``). No entry is a pickle, so a planted file runs no code.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import struct
import sys
import zipfile
import zlib
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import TypeVar

import mujoco
import numpy as np

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
# shape), a missing member (KeyError), a pickled member refused (ValueError), a damaged layout
DAMAGED = (Unusable, OSError, EOFError, ValueError, KeyError, IndexError, TypeError, SyntaxError, MemoryError,
           NotImplementedError, RuntimeError, AttributeError, ImportError, zipfile.BadZipFile, zlib.error,
           struct.error)


def cached_sequence(kind: str, key: str, make: Callable[[], T], save: Callable[[T, Path, str], None],
                    load: Callable[[Path, str], T], cache_dir: Path | None = None, use_cache: bool = True,
                    suffix: str = ".npz", what: str = "sequence") -> T:
    """The sequence under ``key`` in ``<cache_dir>/<kind>/`` when present and sound, else
    ``make()``, stored atomically first. ``save(seq, path, key)`` writes an entry with its key;
    ``load(path, key)`` reads one, raising ``Unusable`` (or one of ``DAMAGED``) when it is not that
    sequence."""
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
    """A cache key (20 hex digits) of a dataclass ``spec`` naming an MJCF ``scene``: its settings,
    the scene's files, a path file's content (``spec.path_digest()``: a waypoint file), the sources
    under ``code``, the entry format and MuJoCo's version."""
    payload = {"spec": asdict(spec), "scene": scene_digest(spec.scene), "code": sources_digest(*code), "format": fmt,
               "mujoco": mujoco.__version__}
    path_file = spec.path_digest() if callable(getattr(spec, "path_digest", None)) else None
    if path_file is not None:   # only then: the keys of every other path stay what they were
        payload["path_file"] = path_file
    return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:20]


STORABLE: dict[str, type] = {}   # the dataclasses an entry may hold, by name (``storable``)
ENTRY = "__entry__"              # the member holding the entry's key and layout (JSON)


def storable(cls: type[T]) -> type[T]:
    """Mark dataclass ``cls`` as one ``save_fields`` may store and ``load_fields`` rebuild (only
    marked classes are built from an entry)."""
    STORABLE[f"{cls.__module__}.{cls.__qualname__}"] = cls
    return cls


def save_fields(seq: object, path: Path, key: str) -> None:
    """Write ``seq`` (a ``storable`` dataclass of arrays, lists of arrays, numbers, strings and
    storable dataclasses) with its ``key`` as a NumPy archive: each array a member (dtype and shape
    kept), the rest JSON; no pickle."""
    arrays: dict[str, np.ndarray] = {}
    layout = _encode(seq, "", arrays)
    arrays[ENTRY] = np.frombuffer(json.dumps({"key": key, "layout": layout}).encode(), np.uint8)
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def load_fields(path: Path, key: str) -> object:
    """The sequence ``save_fields`` wrote under ``key``; ``Unusable`` for another key. No pickles,
    only ``storable`` classes: a planted file is refused, never run."""
    with np.load(path, allow_pickle=False) as z:
        entry = json.loads(z[ENTRY].tobytes())
        if not isinstance(entry, dict) or entry.get("key") != key:
            raise Unusable("it was stored under another key")
        return _decode(entry["layout"], z)


def _encode(value, name: str, arrays: dict) -> dict:
    """``value``'s layout (JSON), its arrays put in ``arrays`` under names below ``name``."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        cls = f"{type(value).__module__}.{type(value).__qualname__}"
        if STORABLE.get(cls) is not type(value):
            raise TypeError(f"{cls} is not marked storable")
        return {"dataclass": cls, "fields": {f.name: _encode(getattr(value, f.name), f"{name}/{f.name}", arrays)
                                             for f in dataclasses.fields(value)}}
    if isinstance(value, (np.ndarray, np.generic)):
        if np.asarray(value).dtype.hasobject:
            raise TypeError(f"{name} holds Python objects")
        arrays[name] = value
        return {"array" if isinstance(value, np.ndarray) else "scalar": name}
    if _ragged(value):   # one array a frame: stored as one, with each frame's length
        arrays[name] = np.concatenate(value)
        return {"ragged": name, "lengths": [len(v) for v in value]}
    if isinstance(value, (list, tuple)):
        return {type(value).__name__: [_encode(v, f"{name}/{i}", arrays) for i, v in enumerate(value)]}
    if value is None or isinstance(value, (bool, int, float, str)):
        return {"value": value}
    raise TypeError(f"{name}: cannot store a {type(value).__name__}")


def _ragged(value) -> bool:
    """Whether ``value`` is a non-empty list of arrays that differ only in their first dimension."""
    return (isinstance(value, list) and bool(value) and all(isinstance(v, np.ndarray) and v.ndim for v in value)
            and len({(v.dtype.str, v.shape[1:]) for v in value}) == 1 and not value[0].dtype.hasobject)


def _decode(layout: dict, z) -> object:
    """The value ``_encode`` laid out, arrays from archive ``z``; a class not marked ``storable`` is
    ``Unusable``."""
    if "dataclass" in layout:
        cls = STORABLE.get(layout["dataclass"])
        if cls is None:
            raise Unusable(f"it holds a {layout['dataclass']}, which no entry may hold")
        return cls(**{k: _decode(v, z) for k, v in layout["fields"].items()})
    if "ragged" in layout:
        return np.split(z[layout["ragged"]], np.cumsum(layout["lengths"])[:-1])
    (kind, body), = layout.items()
    if kind in ("array", "scalar"):
        return z[body] if kind == "array" else z[body][()]
    if kind in ("list", "tuple"):
        items = [_decode(v, z) for v in body]
        return items if kind == "list" else tuple(items)
    if kind == "value":
        return body
    raise Unusable(f"unknown entry layout {kind!r}")
