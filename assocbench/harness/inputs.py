"""A stored run's inputs, as make and DVC keep a dependency file: the source files its run imported,
with digests, and the versions of the libraries that change numbers; a stored run is reused only
while all still match (``RunInputs.changed``), so editing another track's module reuses it. The
files (``ImportGraph.closure``): the modules a run starts from (``roots``), those the worker asked
for (``imports.ImportLog``) and every module their files import (inside functions too); libraries
are not hashed but versioned (``imports.NUMERIC_LIBRARIES``); data files (``*.json``) count with
their module. A file saved after the worker loaded it raises ``Stale``: the run is not stored.
"""

from __future__ import annotations

import ast
import hashlib
import io
import os
import pickle
import site
import sys
import sysconfig
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache
from importlib import metadata
from importlib.machinery import PathFinder
from pathlib import Path

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
DATA_SUFFIXES = (".json",)   # the package's data read by the code beside it (learned models)
HARNESS_ROOT = "assocbench.harness.sandbox"   # what a worker runs: its imports reach the frame loops
# libraries whose version changes a run's numbers, by top-level module, with the distributions that
# provide it: linear algebra, special functions and random streams (numpy, scipy), the compiled
# kernels (numba, llvmlite), ray casts and scene compiling (mujoco), feature detection (cv2), the
# iSAM2 back end (gtsam), the summaries' medians and quantiles (pandas)
LIBRARY_DISTRIBUTIONS = {
    "numpy": ("numpy",), "scipy": ("scipy",), "numba": ("numba",), "llvmlite": ("llvmlite",), "mujoco": ("mujoco",),
    "cv2": ("opencv-python-headless", "opencv-python", "opencv-contrib-python-headless", "opencv-contrib-python"),
    "gtsam": ("gtsam",), "pandas": ("pandas",),
}
NUMERIC_LIBRARIES = tuple(LIBRARY_DISTRIBUTIONS)


class Stale(Exception):
    """A run whose code changed while it ran: its results are not those of the files now."""


@cache
def library_folders() -> tuple[Path, ...]:
    """The standard library's and installed packages' folders (their modules are not hashed)."""
    paths = sysconfig.get_paths()
    found = [paths[k] for k in ("stdlib", "platstdlib", "purelib", "platlib") if k in paths]
    found += list(getattr(site, "getsitepackages", list)()) + [site.getusersitepackages()]
    return tuple(dict.fromkeys(Path(p).resolve() for p in found))


def is_library(path: Path) -> bool:
    """Whether ``path`` belongs to the standard library or an installed package (not this one)."""
    return not path.is_relative_to(PACKAGE_ROOT) and any(path.is_relative_to(f) for f in library_folders())


def file_name(path: Path) -> str:
    """How a stored run names a file: relative to the package for its own (a moved checkout keeps
    its runs), else absolute."""
    return path.relative_to(PACKAGE_ROOT.parent).as_posix() if path.is_relative_to(PACKAGE_ROOT) else str(path)


def file_path(name: str) -> Path:
    """The file a stored run's ``name`` (``file_name``) stands for."""
    path = Path(name)
    return path if path.is_absolute() else PACKAGE_ROOT.parent / path


_DIGESTS: dict[tuple, str] = {}


def file_digest(path: Path) -> tuple[str, int] | None:
    """SHA-256 (16 hex digits) of a file's content and its mtime (ns) after the read; None when
    absent. Re-read only when size or mtime changed."""
    try:
        before = os.stat(path)
        stamp = (str(path), before.st_mtime_ns, before.st_size)
        if stamp in _DIGESTS:
            return _DIGESTS[stamp], before.st_mtime_ns
        data = path.read_bytes()
        after = os.stat(path)
    except OSError:
        return None
    sha = hashlib.sha256(data).hexdigest()[:16]
    if (after.st_mtime_ns, after.st_size) == stamp[1:]:
        _DIGESTS[stamp] = sha
    return sha, after.st_mtime_ns


class ImportGraph:
    """Modules, their files and the modules each file imports, found without importing anything."""

    def __init__(self) -> None:
        self._files: dict[str, Path | None] = {}
        self._edges: dict[tuple, tuple[str, ...]] = {}
        self._data: dict[Path, list[Path]] = {}

    def file(self, name: str) -> Path | None:
        """The file of module ``name`` (a package's ``__init__.py``), None for a built-in or none."""
        if name not in self._files:
            self._files[name] = self._find(name)
        return self._files[name]

    def _find(self, name: str) -> Path | None:
        found = getattr(sys.modules.get(name), "__file__", None)
        if not found:
            parent = name.rpartition(".")[0]
            where = self._search(parent) if parent else None
            if parent and where is None:
                return None
            try:
                spec = PathFinder.find_spec(name, where)
            except (ImportError, ValueError, AttributeError):
                spec = None
            found = spec.origin if spec is not None and spec.has_location else None
        return Path(found).resolve() if found else None

    def _search(self, package: str) -> list[str] | None:
        """Where a package's submodules are looked for."""
        path = getattr(sys.modules.get(package), "__path__", None)
        if path is not None:
            return list(path)
        init = self.file(package)
        return [str(init.parent)] if init is not None and init.name == "__init__.py" else None

    def imports(self, name: str) -> tuple[str, ...]:
        """Every module the file of ``name`` imports, wherever the statement is, and its packages."""
        path = self.file(name)
        if path is None or path.suffix != ".py":
            return ()
        try:
            stamp = (path, path.stat().st_mtime_ns)
        except OSError:
            return ()
        if stamp not in self._edges:
            self._edges[stamp] = tuple(self._read(name, path))
        return self._edges[stamp]

    def _read(self, name: str, path: Path) -> list[str]:
        try:
            tree = ast.parse(path.read_bytes(), str(path))
        except (OSError, SyntaxError, ValueError):
            return []
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        out = _packages(name)[:-1]
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                out += [p for alias in node.names for p in _packages(alias.name)]
            elif isinstance(node, ast.ImportFrom):
                base = _absolute(node.module, node.level, package)
                if base:
                    out += _packages(base)
                    out += [f"{base}.{a.name}" for a in node.names if a.name != "*" and self.file(f"{base}.{a.name}")]
        return list(dict.fromkeys(out))

    def data_files(self, path: Path) -> list[Path]:
        """The package's data files beside the module at ``path`` (none beside another's)."""
        folder = path.parent
        if folder not in self._data:
            self._data[folder] = sorted(f for f in folder.iterdir() if f.suffix in DATA_SUFFIXES) \
                if path.is_relative_to(PACKAGE_ROOT) else []
        return self._data[folder]

    def closure(self, roots: Iterable[str], installed: Iterable[str] = ()) -> set[str]:
        """``roots`` and every module their files import, through source modules; libraries are
        reached, not followed."""
        seen, todo, installed = set(), list(roots), set(installed)
        while todo:
            name = todo.pop()
            if name in seen:
                continue
            seen.add(name)
            path = self.file(name)
            if path is not None and is_source(name, path, installed):
                todo += self.imports(name)
        return seen


def is_source(name: str, path: Path, installed: set[str]) -> bool:
    """Whether module ``name`` at ``path`` is hashed: this package's, any outside the libraries'
    folders, and the ``installed`` top-level packages' (a pip-installed plugin)."""
    return not is_library(path) or name.partition(".")[0] in installed


def _packages(name: str) -> list[str]:
    """``a.b.c`` -> ``a``, ``a.b``, ``a.b.c``: importing a module runs its packages first."""
    parts = name.split(".")
    return [".".join(parts[:k]) for k in range(1, len(parts) + 1)]


def _absolute(module: str | None, level: int, package: str) -> str | None:
    """The absolute name of ``from <level dots><module> import ...`` in ``package``."""
    if not level:
        return module
    parts = package.split(".") if package else []
    if level - 1 > len(parts):
        return None
    base = parts[:len(parts) - (level - 1)]
    return ".".join(base + ([module] if module else [])) or None


class _Modules(pickle.Pickler):
    """Notes the module of every class and function a pickled object refers to."""

    def __init__(self) -> None:
        super().__init__(io.BytesIO(), protocol=pickle.HIGHEST_PROTOCOL)
        self.found: set[str] = set()

    def reducer_override(self, obj):
        for holder in (obj, type(obj)):
            module = getattr(holder, "__module__", None) if isinstance(holder, type) or callable(holder) else None
            if isinstance(module, str):
                self.found.add(module)
        return NotImplemented


def pickled_modules(obj: object) -> set[str]:
    """The modules whose classes and functions ``obj`` refers to: what a worker receiving it
    imports."""
    pickler = _Modules()
    pickler.dump(obj)
    return pickler.found


def library_versions(tops: Iterable[str]) -> dict[str, str]:
    """``{module: "distribution version"}`` of the numeric libraries ``tops`` (``cv2`` ->
    ``opencv-python-headless 4.10.0.84``); "" for none."""
    return {top: next((f"{dist} {_version(dist)}" for dist in LIBRARY_DISTRIBUTIONS[top] if _version(dist)), "")
            for top in tops if top in LIBRARY_DISTRIBUTIONS}


@cache
def _version(dist: str) -> str:
    """An installed distribution's version ("" if none), read once a process (reading scans every
    distribution)."""
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return ""


@dataclass(frozen=True)
class RunInputs:
    """A stored run's inputs: ``files`` (``file_name`` -> digest) and ``libraries`` (top-level module
    -> ``"distribution version"``, ``library_versions``)."""

    files: dict[str, str]
    libraries: dict[str, str]

    def changed(self) -> str | None:
        """The first input that differs now, in words; None when every one still matches."""
        for name, sha in sorted(self.files.items()):
            now = file_digest(file_path(name))
            if now is None:
                return f"{name} is gone"
            if now[0] != sha:
                return f"{name} changed"
        now = library_versions(self.libraries)
        for top, version in sorted(self.libraries.items()):
            if now.get(top) != version:
                return f"{version or top} is now {now.get(top) or 'not installed'}"
        return None

    def to_json(self) -> dict:
        return {"files": dict(sorted(self.files.items())), "libraries": dict(sorted(self.libraries.items()))}

    @classmethod
    def from_json(cls, data: dict) -> RunInputs:
        files, libraries = data["files"], data["libraries"]
        if not all(isinstance(d, dict) and all(isinstance(v, str) for v in d.values()) for d in (files, libraries)):
            raise ValueError("inputs must map names to strings")
        return cls(dict(files), dict(libraries))


def run_inputs(graph: ImportGraph, roots: Iterable[str], report: dict, installed: Iterable[str] = ()) -> RunInputs:
    """The inputs of a method's run from its ``roots`` and the worker's ``report``; ``Stale`` when a
    file was saved after it loaded."""
    loaded = {str(Path(path).resolve()): at for path, at in report["loaded"].items()}
    files, tops, installed = {}, set(), set(installed)
    for name in sorted(graph.closure(set(roots) | set(report["names"]), installed)):
        path = graph.file(name)
        if path is None:
            continue
        if not is_source(name, path, installed):
            tops.add(name.partition(".")[0])
            continue
        for f in [path, *graph.data_files(path)]:
            got = file_digest(f)
            if got is None:
                continue
            since = loaded.get(str(f)) if f == path else report["earliest"]
            if since is not None and got[1] / 1e9 > since:
                raise Stale(f"{file_name(f)} was saved after the run loaded it")
            files[file_name(f)] = got[0]
    return RunInputs(files, library_versions(sorted(tops & set(report["libraries"]))))  # loaded and imported


def run_roots(spec, method: str) -> tuple[set[str], set[str]]:
    """The modules a worker starts a run from (``HARNESS_ROOT``, the track's, the spec's, the method
    class's) and their top-level packages (hashed even when installed)."""
    from ..associators.registry import associator_class

    own = {type(spec.track_impl).__module__}
    try:
        own.add(associator_class(method).__module__)
    except Exception:  # noqa: BLE001 - oracle, a track's own method: the worker's log has what it loaded
        pass
    return {HARNESS_ROOT} | own | pickled_modules(spec), {name.partition(".")[0] for name in own}
