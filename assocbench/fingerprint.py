"""Fingerprints of the code behind a cached result, so a cache never outlives the code that made it.

A leaderboard job and a rendered sequence are stored under keys that hash their settings; these
digests join the keys, so editing an associator (or a plugin, helpers included), the detector
or the truth labelling makes the next sweep recompute instead of reusing results the old code
produced.

Which files key a method (``class_digest``):

* a class in a package (``mypkg.sub.mod:Cls``): every ``.py`` file under its top-level package
  folder (``mypkg/``), so an edit to any helper module of the package counts;
* a class in a top-level module (``plug.py``): that file and the other ``.py`` files in its
  folder (not subfolders), where a single-file plugin keeps its helpers; a module in
  site-packages or the standard library: its own file only;
* an installed distribution also adds its name and version;
* a tree of more than ``MAX_FILES`` files is not hashed whole: the module's own file is, and a
  warning says that editing its helpers will not invalidate stored results.
"""

from __future__ import annotations

import hashlib
import inspect
import sys
import sysconfig
from functools import cache, lru_cache
from importlib import metadata
from pathlib import Path

PACKAGE_ROOT = Path(__file__).resolve().parent
MAX_FILES = 2000  # a plugin's source tree bigger than this is not read whole (a home folder)


def source_digest(root: Path) -> str:
    """SHA-256 (16 hex digits) of every ``.py`` file under ``root`` (or of ``root`` itself).
    Files are re-read only when one's size or modification time changed, so a file edited in a
    running session (a notebook) is noticed."""
    files = tuple(sorted(root.rglob("*.py"))) if root.is_dir() else (root,)
    return files_digest(files, root.parent)


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
    """Digest of this package's sources (or of one subpackage, e.g. ``"sim"``) and of the models
    shipped as data (``*.json``: the learned associator's trees), so a retrained model never
    reuses the numbers of the old one."""
    root = PACKAGE_ROOT / subpackage if subpackage else PACKAGE_ROOT
    return files_digest(tuple(sorted(root.rglob("*.py")) + sorted(root.rglob("*.json"))), root.parent)


def sources_digest(*subpackages: str) -> str:
    """Digest of the sources under several subpackage folders (``"sim"``, ``"tracks/camera"``):
    what a cached sequence is keyed by, so editing a measurement model or the track's own sensor
    re-renders it while editing another track does not."""
    files = tuple(sorted(f for sub in subpackages for f in (PACKAGE_ROOT / sub).rglob("*.py")))
    return files_digest(files, PACKAGE_ROOT)


def class_digest(cls: type) -> str:
    """Digest of the code behind ``cls`` by the rule in this module's docstring; its qualified
    name if it has no source file."""
    try:
        path = Path(inspect.getsourcefile(cls)).resolve()
    except (TypeError, OSError):
        return f"{cls.__module__}.{cls.__qualname__}"
    top = cls.__module__.partition(".")[0]
    files, base = _source_tree(top, path)
    return f"{_distribution(top)}{files_digest(files, base)}"


def _source_tree(top: str, path: Path) -> tuple[tuple[Path, ...], Path]:
    """The files that key a module at ``path`` whose top-level package is ``top``, and the
    folder their names are taken relative to."""
    package = sys.modules.get(top)
    init = getattr(package, "__file__", None)
    if getattr(package, "__path__", None) is not None and init:
        root = Path(init).resolve().parent
        files = _bounded(root.rglob("*.py"), path, root)
    elif path.parent in _library_folders():
        root, files = path.parent, (path,)
    else:
        root = path.parent
        files = _bounded(root.glob("*.py"), path, root)
    return files, root.parent


def _bounded(found, own: Path, root: Path) -> tuple[Path, ...]:
    files = []
    for f in found:
        files.append(f)
        if len(files) > MAX_FILES:
            _warn_once(f"assocbench: {root} has more than {MAX_FILES} .py files: results of {own.name} are keyed "
                       "by that file alone, so editing a module it imports will not make them recompute")
            return (own,)
    return tuple(sorted(files))


@cache
def _warn_once(message: str) -> None:
    print(message, file=sys.stderr)


@lru_cache(maxsize=1)
def _library_folders() -> frozenset[Path]:
    """Folders of the standard library and of installed packages (never hashed whole)."""
    paths = sysconfig.get_paths()
    return frozenset(Path(paths[k]).resolve() for k in ("stdlib", "platstdlib", "purelib", "platlib") if k in paths)


@cache
def _distribution(top: str) -> str:
    """``name==version:`` of the installed distribution providing ``top``, or ``""``."""
    try:
        names = metadata.packages_distributions().get(top, [])
        return "".join(f"{n}=={metadata.version(n)}:" for n in sorted(set(names)))
    except Exception:  # noqa: BLE001 - broken metadata must not stop a sweep from being planned
        return ""
