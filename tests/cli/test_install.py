"""A non-editable install into a fresh virtual environment ships the scenes and the console script."""

from __future__ import annotations

import os
import site
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow   # packaging: builds a wheel and installs it (the longest test, minutes); CI runs it
def test_fresh_venv_pip_install_then_assocbench_run(tmp_path):
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    py = env_dir / "bin" / "python"
    purelib = Path(subprocess.check_output([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                           text=True).strip())
    # dependencies come from this interpreter's site-packages (no network in a test); the package
    # itself is built and installed from the source tree, not editable
    deps = [sysconfig.get_paths()["purelib"], *site.getsitepackages()]
    (purelib / "deps.pth").write_text("\n".join(dict.fromkeys(deps)) + "\n")
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(wheels),
                    str(ROOT)], check=True, capture_output=True, text=True)
    subprocess.run([str(py), "-m", "pip", "install", "--no-deps", "-q", *map(str, wheels.glob("*.whl"))],
                   check=True, capture_output=True, text=True)
    work = tmp_path / "work"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    where = subprocess.check_output([str(py), "-c", "import assocbench; print(assocbench.__file__)"], text=True, cwd=work, env=env)
    assert str(env_dir) in where                                   # the installed copy, not the source tree
    proc = subprocess.run([str(env_dir / "bin" / "assocbench"), "run", "--method", "jcbb", "--frames", "3"],
                          capture_output=True, text=True, cwd=work, env=env)
    assert proc.returncode == 0, proc.stderr
    assert "precision" in proc.stdout
    (run_dir,) = (work / "results" / "runs").glob("room-jcbb-seed0-*")   # named by a digest of its settings
    assert f"{run_dir.relative_to(work)}/summary.csv" in proc.stdout
    summary = pd.read_csv(run_dir / "summary.csv")
    assert summary.loc[0, "frames"] == 3 and summary.loc[0, "precision"] > 0.5
    # the report's stylesheet and script are package data, inlined into its pages
    proc = subprocess.run([str(env_dir / "bin" / "assocbench"), "report", str(ROOT / "results" / "planar"), "--out",
                           "report"], capture_output=True, text=True, cwd=work, env=env)
    assert proc.returncode == 0, proc.stderr
    page = (work / "report" / "planar-closed-loop.html").read_text()
    assert "th.sortable" in page and "function sortBy" in page


def test_compiled_kernels_are_cached_per_source_version(tmp_path):
    """numba re-checks only a kernel's own file, yet a kernel embeds the kernels it calls from other
    files; the cache folder is keyed by the digest of all sources, so an edit never runs stale code."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"} | {"ASSOCBENCH_CACHE": str(tmp_path)}
    code = "import os, assocbench; from assocbench.fingerprint import package_digest; " \
           "print(os.environ['NUMBA_CACHE_DIR']); print(package_digest())"
    folder, digest = subprocess.check_output([sys.executable, "-c", code], env=env, text=True, cwd=ROOT).split()
    assert Path(folder) == tmp_path / "numba" / digest
