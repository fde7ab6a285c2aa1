"""Imported once by the forkserver that forks the worker processes (``sandbox.py``), never by
a user: it imports what a worker runs and loads the compiled kernels of the built-in associators
and of the tracks the server was started for (compiling them if numba's cache is cold), so every
worker forked from it starts warm instead of paying a second or more per process."""

import json
import os

from ..associators.registry import BUILTINS
from .sandbox import SAVED_ENV, TRACKS_ENV, restore_env, warm_builtins

if SAVED_ENV in os.environ:  # the server was started with its path pinned (sandbox._start_forkserver)
    restore_env(json.loads(os.environ.pop(SAVED_ENV)))

tracks = json.loads(os.environ.pop(TRACKS_ENV, "[]"))   # not inherited by the workers' own children
try:
    warm_builtins(BUILTINS, tracks)
except Exception:  # noqa: BLE001 - never stop the forkserver: a worker then warms up by itself
    pass
