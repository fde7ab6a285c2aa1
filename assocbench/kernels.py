"""Compiled kernels: a cache that heals, and one line on stderr while they compile. Both sit on
numba's cache-loading path, once per kernel and signature, never in timed calls:

* a damaged cache file would make numba raise on every run until deleted by hand; ``install`` wraps
  ``Cache.load_overload`` so it is deleted with one line on stderr and recompiled, and an unwritable
  cache costs only the caching;
* ``warm(calls)`` runs calls that load kernels and, when one compiles, says so on stderr: one line,
  a dot per kernel and the time taken. A warm cache prints nothing.
"""

from __future__ import annotations

import functools
import glob
import sys
import time
from collections.abc import Callable, Iterable
from pathlib import Path

_state = {"active": False, "started": None, "noted": False, "what": "", "expect": 30}


def install() -> None:
    """Make numba's cache heal damaged files and report compilation (idempotent)."""
    try:
        from numba.core.caching import Cache
    except ImportError:  # a numba without this class: keep its own behaviour
        return
    if getattr(Cache.load_overload, "_assocbench", False):
        return
    load, save = Cache.load_overload, Cache.save_overload

    @functools.wraps(load)
    def load_overload(self, sig, target_context):
        try:
            data = load(self, sig, target_context)
        except Exception as exc:  # noqa: BLE001 - any failure to load a cache entry means "damaged"
            _discard(self, exc)
            data = None
        if data is None:
            _compiling(self)
        return data

    @functools.wraps(save)
    def save_overload(self, sig, data):
        try:
            save(self, sig, data)
        except Exception as exc:  # noqa: BLE001 - the kernel is compiled; only caching it failed
            print(f"assocbench: could not cache compiled kernel {_name(self)} in {_folder(self)} "
                  f"({type(exc).__name__}: {exc}); it will be compiled again next run", file=sys.stderr)

    load_overload._assocbench = True
    Cache.load_overload, Cache.save_overload = load_overload, save_overload


# about what the association kernels' first compile takes for `assocbench run --method jcbb` from a
# fresh clone on a 2-core machine; benchmarks/first_run.py measures it, and
# tests/docs/test_benchmark_records.py holds this figure to that script's record
ASSOCIATION_COMPILE_S = 130


def warm(calls: Iterable[Callable[[], object]], what: str = "association kernels",
         expect_s: float = ASSOCIATION_COMPILE_S) -> float | None:
    """Run ``calls``; when a kernel compiles, print ``compiling <what> (...)...``, a dot per kernel
    and ``done in N s``. Returns the seconds compiling, ``None`` when all came from the cache;
    errors are left to the real call. ``expect_s``: a cold compile's rough time, for the note."""
    _state.update(active=True, started=None, what=what, expect=expect_s)
    try:
        for call in calls:
            try:
                call()
            except Exception:  # noqa: BLE001
                pass
    finally:
        _state["active"] = False
    if _state["started"] is None:
        return None
    seconds = time.perf_counter() - _state["started"]
    print(f" done in {seconds:.0f} s", file=sys.stderr, flush=True)
    return seconds


def _compiling(cache) -> None:
    """A kernel is about to be compiled (its cache entry is missing or was discarded)."""
    if _state["active"]:
        if _state["started"] is None:
            _state["started"] = time.perf_counter()
            print(f"assocbench: compiling {_state['what']} (once per environment and version of the sources, ~{_state['expect']:.0f} s) ",
                  end="", file=sys.stderr, flush=True)
        print(".", end="", file=sys.stderr, flush=True)
    elif not _state["noted"] and _module(cache).startswith("assocbench"):
        _state["noted"] = True  # compiled outside warm(): a plain line, once
        print(f"{_fresh_line()}assocbench: compiling {_module(cache)} kernels at their first use (once per "
              f"environment)", file=sys.stderr, flush=True)


def _fresh_line() -> str:
    """On a terminal, a carriage return and erase, so a worker's note replaces a progress bar's
    line."""
    try:
        return "\r\033[K" if sys.stderr.isatty() else ""
    except (AttributeError, ValueError):   # a replaced or closed stderr
        return ""


def _discard(cache, exc: Exception) -> None:
    """Delete the index and data files of the kernel whose cache entry failed to load."""
    index = Path(getattr(getattr(cache, "_cache_file", None), "_index_path", "") or "")
    files = [index, *index.parent.glob(glob.escape(index.stem) + ".*.nbc")] if index.name else []
    for path in files:
        try:
            path.unlink(missing_ok=True)
        except OSError:
            pass  # saving the recompiled kernel replaces it
    _state["noted"] = True  # this line already says a kernel compiles
    if _state.get("discarded"):
        return   # one line per process: a cache damaged as a whole would otherwise print a line per kernel
    _state["discarded"] = True
    mid_line = _state["active"] and _state["started"] is not None  # after the dots of the compile note
    print(f"{chr(10) if mid_line else ''}assocbench: damaged numba cache entry ({_name(cache)}: {type(exc).__name__}) "
          f"in {index.parent}; deleting it, and any other damaged entry, and compiling again",
          file=sys.stderr, flush=True)


def _name(cache) -> str:
    func = getattr(cache, "_py_func", None)
    return f"{_module(cache)}.{getattr(func, '__qualname__', '?')}"


def _module(cache) -> str:
    return str(getattr(getattr(cache, "_py_func", None), "__module__", "") or "")


def _folder(cache) -> str:
    return str(getattr(cache, "_cache_path", "?"))
