"""A progress bar over a run's frames on stderr (``assocbench run`` on a terminal). The supervisor
hears each call and finished frame (``Supervisor(watch=...)``); the bar names the phase (preparing
the sequence, building and warming the method, the frames). On a terminal it redraws every ``tick``
so the elapsed time moves; a log file gets a line per event. A terminal reporting no size gets 80 x
24 (tqdm hides a bar of 0 rows). tqdm's monitor thread is off: a second thread would make workers
start from a forkserver (``sandbox._context``).
"""

from __future__ import annotations

import shutil
import sys
from typing import TextIO

from tqdm import tqdm

from .runner import WARM_UP


class _Bar(tqdm):
    monitor_interval = 0   # no monitor thread (module docstring)


class RunProgress:
    """The bar of one run of ``frames`` frames of ``method`` (``watch`` is the Supervisor's hook)."""

    def __init__(self, method: str, frames: int, file: TextIO | None = None) -> None:
        self.method, self.frames, self.file = method, int(frames), file or sys.stderr
        self.bar: tqdm | None = None
        self.live = bool(getattr(self.file, "isatty", lambda: False)())

    def watch(self, event: str, k: int) -> None:
        """``start`` (worker launched), ``call`` (the method on frame ``k``; ``WARM_UP``: built and
        warmed), ``frame`` (frame ``k`` done), ``tick``."""
        if self.bar is None:   # made here, after any compile in this process has printed its line
            size = shutil.get_terminal_size()   # 80 x 24 where the terminal reports 0 (tqdm would hide the bar)
            self.bar = _Bar(total=self.frames, desc="preparing the sequence", unit="frame", file=self.file,
                            ncols=size.columns, nrows=size.lines, mininterval=0.2)
        if event == "call" and k == WARM_UP:
            self.bar.set_description(f"building and warming up {self.method}", refresh=False)
        elif event == "call" and k == 0:   # the frames start: their rate and the time left count
            self.bar.reset(total=self.frames)   # from here, not from the sequence and the warm-up
        elif event == "frame":
            self.bar.set_description(self.method, refresh=False)
            self.bar.update(k + 1 - self.bar.n)
        if event != "tick" or self.live:   # a log file gets the events, a terminal the clock too
            self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
