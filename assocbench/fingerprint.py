"""Fingerprints of the code behind cached data, so a cache never outlives the code that made it:
``sources_digest`` of the folders that make a sequence joins its key (editing a sensor re-renders
it); ``package_digest`` names the kernels' folder and an exported dataset's code. Stored leaderboard
runs record their imported files instead (``harness.inputs``).
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

PACKAGE_ROOT = Path(__file__).resolve().parent


def files_digest(files, base: Path) -> str:
    """SHA-256 (16 hex digits) of ``files``' names relative to ``base`` and their contents."""
    stamp = tuple((str(f), f.stat().st_mtime_ns, f.stat().st_size) for f in files)
    return _digest(base, stamp)


@lru_cache(maxsize=256)
def _digest(base: Path, stamp: tuple) -> str:
    h = hashlib.sha256()
    for name, _, _ in stamp:
        path = Path(name)
        h.update(str(path.relative_to(base)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def package_digest(subpackage: str = "") -> str:
    """Digest of this package's sources (or a subpackage's) and its data models (``*.json``), so a
    retrained model never reuses the old one's numbers."""
    root = PACKAGE_ROOT / subpackage if subpackage else PACKAGE_ROOT
    return files_digest(tuple(sorted(root.rglob("*.py")) + sorted(root.rglob("*.json"))), root.parent)


def sources_digest(*subpackages: str) -> str:
    """Digest of the sources under several subpackage folders: a cached sequence's key, so editing a
    track's own sensor re-renders it and editing another track does not."""
    files = tuple(sorted(f for sub in subpackages for f in (PACKAGE_ROOT / sub).rglob("*.py")))
    return files_digest(files, PACKAGE_ROOT)
