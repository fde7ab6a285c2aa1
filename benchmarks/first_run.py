"""What a first run costs on a fresh machine: numba compiling each group of kernels into an empty cache, and the README's first command from empty caches.

Each row runs in a fresh process whose kernel cache (NUMBA_CACHE_DIR) and sequence cache
(ASSOCBENCH_CACHE) are new temporary folders. Kernel groups: the warm-up that compiles them, as the
harness or the track runs it before its first frame (``kernels.warm``, which prints the notice
"compiling ... (~N s)"), timed from its call to its return; beside it the N its notice announces.
The first command: ``assocbench run --method jcbb`` (the room, 40 frames rendered, its kernels
compiled), timed end to end, and the compile time its notice reports ("done in N s").

Usage: python benchmarks/first_run.py [--skip-run]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _util import print_table, run_recorded

# group: (what the process runs, the stage of a run it stands for)
GROUPS = {
    "association kernels, jcbb": ("from assocbench.harness.sandbox import warm_builtins; warm_builtins(['jcbb'])",
                                  "`run --method jcbb`, before its first frame"),
    "association kernels, every built-in": (
        "from assocbench.associators.registry import BUILTINS; from assocbench.harness.sandbox import warm_builtins; "
        "warm_builtins(list(BUILTINS))", "a leaderboard's workers"),
    "dense kernels": ("from assocbench.tracks.dense.warm import warm_dense; warm_dense()", "a dense run"),
    "fusion kernels": ("from assocbench.tracks.dense.fusion import warm_fusion; warm_fusion()", "dense fusion alone"),
    "line extraction kernels": ("from assocbench.tracks.lines.sequence import warm_extraction; warm_extraction()",
                                "a lines sequence"),
}
TIMED = "import time; {setup}; start = time.perf_counter(); {call}; print(time.perf_counter() - start)"


def fresh_env(tmp: Path) -> dict[str, str]:
    """The environment with empty kernel and sequence caches under ``tmp``."""
    env = {**os.environ, "ASSOCBENCH_CACHE": str(tmp / "cache"), "NUMBA_CACHE_DIR": str(tmp / "numba")}
    env.pop("ASSOCBENCH_NO_RECORD", None)
    return env


def compile_group(code: str) -> tuple[float, str]:
    """Seconds the group's warm-up took in a fresh process with empty caches, and its notice's ``~N``."""
    setup, _, call = code.rpartition("; ")
    with tempfile.TemporaryDirectory() as tmp:
        done = subprocess.run([sys.executable, "-c", TIMED.format(setup=setup, call=call)], env=fresh_env(Path(tmp)),
                              capture_output=True, text=True, check=True)
    announced = re.search(r"~(\d+) s\)", done.stderr)
    return float(done.stdout.split()[-1]), announced.group(1) if announced else "(no notice)"


def first_command() -> list[object]:
    """``assocbench run --method jcbb`` with empty caches: wall seconds and the compile notice's time."""
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "assocbench.cli.main", "run", "--method", "jcbb", "--no-progress",
                               "--out", str(Path(tmp) / "out")], env=fresh_env(Path(tmp)), capture_output=True,
                              text=True, check=True)
        wall = time.perf_counter() - start
    compiled = re.search(r"done in (\d+) s", done.stderr)
    return ["assocbench run --method jcbb", wall, compiled.group(1) if compiled else "(no notice)"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--skip-run", action="store_true", help="time the kernel groups only, not the first command")
    args = ap.parse_args()
    print(f"each row in a fresh process with empty caches; {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}")
    rows = []
    for group, (code, stage) in GROUPS.items():
        seconds, announced = compile_group(code)
        rows.append([group, stage, seconds, announced])
    print_table(["kernels", "compiled for", "seconds", "its notice says ~s"], rows)
    if not args.skip_run:
        print_table(["first command, empty caches", "wall seconds", "of which compiling (its notice), s"],
                    [first_command()])


if __name__ == "__main__":
    run_recorded(main)
