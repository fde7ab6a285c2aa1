"""The forkserver's workers import the assocbench the main process runs, not a copy in the working
folder (Python 3.11's forkserver starts with ``python -c`` and ignores the parent's sys.path)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import assocbench

SCRIPT = '''
import os, threading
from assocbench.harness.sandbox import _context

if __name__ == "__main__":
    stop = threading.Event()
    threading.Thread(target=stop.wait, daemon=True).start()   # a thread: _context picks the forkserver
    ctx = _context(["mnn"])
    assert ctx.get_start_method() == "forkserver"
    child = ctx.Process(target=print, args=("worker ran",))
    child.start()
    child.join()
    stop.set()
    assert child.exitcode == 0, child.exitcode
    assert "PYTHONSAFEPATH" not in os.environ and "ASSOCBENCH_FORKSERVER_SAVED_ENV" not in os.environ
    print("parent ok")
'''


def test_forkserver_workers_ignore_an_assocbench_folder_in_the_working_folder(tmp_path):
    """Run from a clone after ``pip install .``, workers imported the clone (marker written)."""
    clone, scripts = tmp_path / "clone", tmp_path / "scripts"
    (clone / "assocbench").mkdir(parents=True)
    scripts.mkdir()
    marker = tmp_path / "decoy_imported"
    (clone / "assocbench" / "__init__.py").write_text(f"open({str(marker)!r}, 'w').close()\nraise ImportError\n")
    (scripts / "start.py").write_text(SCRIPT)
    installed = str(Path(assocbench.__file__).resolve().parents[1])
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONSAFEPATH", "PYTHONPATH")}
    env["PYTHONPATH"] = installed
    done = subprocess.run([sys.executable, str(scripts / "start.py")], cwd=clone, env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "worker ran" in done.stdout and "parent ok" in done.stdout
    assert not marker.exists(), "the forkserver imported the working folder's assocbench"


WARMED_SCRIPT = '''
import threading
from assocbench.harness import sandbox


def report():
    print("warmed", sorted(sandbox._warm))


if __name__ == "__main__":
    threading.Thread(target=threading.Event().wait, daemon=True).start()   # a thread: the forkserver
    ctx = sandbox._context(["projective"], ["dense"])
    child = ctx.Process(target=report)
    child.start()
    child.join()
    assert child.exitcode == 0, child.exitcode
'''


def test_a_dense_runs_forkserver_warms_its_track_not_the_feature_associators(tmp_path):
    """The server warmed every built-in feature associator and their scoring for any first task:
    a first dense run on a cold machine compiled them for 93-109 s and never called them. It warms
    the first task's methods and track; a worker forked from it inherits just those."""
    script = tmp_path / "warmed.py"
    script.write_text(WARMED_SCRIPT)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    warmed = done.stdout.split("warmed")[1].strip()
    assert "'track dense'" in warmed and "jcbb" not in warmed and "'scoring'" not in warmed, warmed
