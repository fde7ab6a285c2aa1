"""A worker's log of the modules each run asks for by name, for the stored run's inputs
(``inputs.py`` adds what those import): a module loaded while the run ran (a plugin's helper, a lazy
kernel) or asked for by a string (``importlib.import_module``), even one a forked worker already
had. Logged per method (``begin_method``) and, for what a run's methods share
(``for_every_method``), per run (``begin_run``); nothing outside a worker.
"""

from __future__ import annotations

import _frozen_importlib as _bootstrap
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from .. import _load_times
from .inputs import NUMERIC_LIBRARIES, is_library


class ImportLog:
    """The names asked for since ``begin_run`` (shared by the run's methods) and ``begin_method``."""

    def __init__(self) -> None:
        self.shared: set[str] = set()
        self.own: set[str] = set()
        self._into = self.own

    def note(self, name: str) -> None:
        self._into.add(name)

    def begin_run(self) -> None:
        self.shared, self.own = set(), set()
        self._into = self.own

    def begin_method(self) -> None:
        self.own = set()
        self._into = self.own

    @contextmanager
    def for_every_method(self) -> Iterator[None]:
        """What is asked for inside counts for every method of the run."""
        before, self._into = self._into, self.shared
        try:
            yield
        finally:
            self._into = before

    def report(self) -> dict:
        """What the parent needs for ``inputs.run_inputs``: names asked for, each source module's
        load time, the numeric libraries loaded, this worker line's start."""
        loaded = {}
        for name, module in list(sys.modules.items()):
            path = getattr(module, "__file__", None)
            if isinstance(path, str) and path.endswith(".py") and _source(path):
                loaded[path] = _load_times.loaded_at(name)
        return {"names": sorted(self.shared | self.own), "loaded": loaded, "earliest": _load_times.EARLIEST,
                "libraries": [lib for lib in NUMERIC_LIBRARIES if lib in sys.modules]}


_SOURCE: dict[str, bool] = {}


def _source(path: str) -> bool:
    """Whether a module file is a source file (not a library's), answered once per file."""
    if path not in _SOURCE:
        _SOURCE[path] = not is_library(Path(path).resolve())
    return _SOURCE[path]


_log: ImportLog | None = None


def start() -> ImportLog:
    """Log this process's imports from now on (a worker calls it once)."""
    global _log
    if _log is None:
        _log = ImportLog()
        _load_times.listeners.append(lambda name: _log.note(name))
        real = _bootstrap._gcd_import

        def gcd_import(name: str, package: str | None = None, level: int = 0):
            _log.note(_bootstrap._resolve_name(name, package, level) if level else name)
            return real(name, package, level)

        _bootstrap._gcd_import = gcd_import   # what importlib.import_module calls, looked up per call
    return _log


@contextmanager
def for_every_method() -> Iterator[None]:
    """``ImportLog.for_every_method`` of this worker's log; nothing outside a worker."""
    if _log is None:
        yield
    else:
        with _log.for_every_method():
            yield
