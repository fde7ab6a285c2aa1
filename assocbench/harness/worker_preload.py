"""Imported once by the forkserver that forks the workers (``sandbox.py``), never by a user: it
imports what a worker runs and loads the kernels of the built-in associators and the tracks the
server was started for, so every forked worker starts warm."""

import json
import os

from ..associators.registry import BUILTINS
from .sandbox import METHODS_ENV, SAVED_ENV, TRACKS_ENV, restore_env, warm_builtins

if SAVED_ENV in os.environ:  # the server was started with its path pinned (sandbox._start_forkserver)
    restore_env(json.loads(os.environ.pop(SAVED_ENV)))

tracks = json.loads(os.environ.pop(TRACKS_ENV, "[]"))   # not inherited by the workers' own children
methods = json.loads(os.environ.pop(METHODS_ENV, "null"))
try:
    warm_builtins(BUILTINS if methods is None else methods, tracks)
except Exception:  # noqa: BLE001 - never stop the forkserver: a worker then warms up by itself
    pass
