"""When each module of this process was loaded, so a source file saved after its module loaded is
noticed (the code that ran is not the file's: ``harness.inputs``). A finder first on
``sys.meta_path`` notes the time of every import reaching the finders and finds nothing itself; a
module loaded before this one counts as loaded at process start. A forked process inherits both;
``listeners`` hear each name looked for.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

_LOADED: dict[str, float] = {}
listeners: list[Callable[[str], None]] = []


def _process_start() -> float:
    """Wall-clock start of this process (Linux ``/proc``; its boot time has whole seconds, so one is
    taken off), else now."""
    try:
        ticks = int(Path("/proc/self/stat").read_text().rpartition(")")[2].split()[19])
        boot = next(float(line.split()[1]) for line in Path("/proc/stat").read_text().splitlines()
                    if line.startswith("btime "))
        return boot + ticks / os.sysconf("SC_CLK_TCK") - 1.0
    except (OSError, ValueError, IndexError, StopIteration):
        return time.time()


EARLIEST = _process_start()   # what a module loaded before this one counts as (kept across a fork)


class _Clock:
    """A meta-path finder that finds nothing: it notes when each module was looked for."""

    def find_spec(self, fullname: str, path=None, target=None) -> None:
        _LOADED[fullname] = time.time()
        for listener in listeners:
            listener(fullname)
        return None


def loaded_at(name: str) -> float:
    """When module ``name`` was (last) loaded in this process or the one it was forked from."""
    return _LOADED.get(name, EARLIEST)


if not any(isinstance(finder, _Clock) for finder in sys.meta_path):
    sys.meta_path.insert(0, _Clock())
