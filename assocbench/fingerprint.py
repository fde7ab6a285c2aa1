"""Fingerprints of the code behind a cached result, so a cache never outlives the code that made it.

A leaderboard job and a rendered sequence are stored under keys that hash their settings; these
digests join the keys, so editing an associator (or a plugin's file), the detector or the truth
labelling makes the next sweep recompute instead of reusing results the old code produced.
"""

from __future__ import annotations

import hashlib
import inspect
from functools import lru_cache
from pathlib import Path

PACKAGE_ROOT = Path(__file__).resolve().parent


def source_digest(root: Path) -> str:
    """SHA-256 (16 hex digits) of every ``.py`` file under ``root`` (or of ``root`` itself).
    Files are re-read only when one's size or modification time changed, so a file edited in a
    running session (a notebook) is noticed."""
    files = tuple(sorted(root.rglob("*.py"))) if root.is_dir() else (root,)
    stamp = tuple((str(f), f.stat().st_mtime_ns, f.stat().st_size) for f in files)
    return _digest(root, stamp)


@lru_cache(maxsize=256)
def _digest(root: Path, stamp: tuple) -> str:
    h = hashlib.sha256()
    for name, _, _ in stamp:
        path = Path(name)
        h.update(str(path.relative_to(root.parent)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def package_digest(subpackage: str = "") -> str:
    """Digest of this package's sources (or of one subpackage, e.g. ``"sim"``)."""
    return source_digest(PACKAGE_ROOT / subpackage if subpackage else PACKAGE_ROOT)


def class_digest(cls: type) -> str:
    """Digest of the file that defines ``cls`` (a plugin's module); its qualified name if it has no file."""
    try:
        return source_digest(Path(inspect.getsourcefile(cls)).resolve())
    except (TypeError, OSError):
        return f"{cls.__module__}.{cls.__qualname__}"
