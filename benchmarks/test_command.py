"""What the README's test command costs from a fresh clone: the install, the default test set on one worker per core, and the CI accuracy guard, each timed, with empty caches.

The command is read from the README (the code block after "Install and run the tests") and its
`&&`-joined steps are run one by one in a clone of this checkout's HEAD, in a new temporary
folder, with ``ASSOCBENCH_CACHE`` at a new empty folder and ``NUMBA_CACHE_DIR`` unset, so numba
compiles every kernel inside the test run as on a fresh machine (pip's own download cache is
kept: the network is not what this measures). Then the test step once more, kernels and
sequences cached: what a second run costs. A step that fails stops the script with its exit code.

Usage: python benchmarks/test_command.py
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

from _util import ROOT, print_table, run_recorded


def readme_test_command(readme: Path = ROOT / "README.md") -> list[str]:
    """The README's test command, split into its ``&&`` steps."""
    text = readme.read_text()
    block = re.search(r"Install and run the tests.*?```bash\n(.*?)\n```", text, re.S)
    if block is None:
        sys.exit("test_command.py: error: README.md has no code block after 'Install and run the tests'")
    return [step.strip() for step in block.group(1).split("&&")]


def timed_step(step: str, cwd: Path, env: dict[str, str]) -> float:
    """Run one step in a shell in ``cwd``; its wall seconds, or exit with its code if it fails."""
    start = time.perf_counter()
    done = subprocess.run(step, shell=True, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True)
    seconds = time.perf_counter() - start
    if done.returncode:
        print(done.stdout[-3000:], file=sys.stderr)
        sys.exit(f"test_command.py: error: `{step}` failed with exit code {done.returncode}")
    tail = done.stdout.strip().splitlines()[-1:] or [""]
    print(f"{step}: {seconds:.0f} s; {tail[0]}", file=sys.stderr)
    return seconds


def main() -> int:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()
    steps = readme_test_command()
    with tempfile.TemporaryDirectory(prefix="assocbench-fresh-") as tmp:
        clone, cache = Path(tmp) / "clone", Path(tmp) / "cache"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
        env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "MUJOCO_GL", "VIRTUAL_ENV")}
        env["ASSOCBENCH_CACHE"] = str(cache)
        rows = [[step, f"{timed_step(step, clone, env):.0f}"] for step in steps]
        tests = next((s for s in steps if "pytest" in s), None)
        if tests is not None:
            rows.append([f"{tests} (again, caches warm)", f"{timed_step(tests, clone, env):.0f}"])
    rows.append(["the whole command, empty caches", f"{sum(float(r[1]) for r in rows[:len(steps)]):.0f}"])
    print_table(["step", "wall s"], rows)
    return 0


if __name__ == "__main__":
    run_recorded(main)
