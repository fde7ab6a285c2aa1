"""Process defaults applied before numpy or mujoco load (each only if the user set nothing).

* ``MUJOCO_GL=egl``: EGL renders headless; osmesa and glfw do not on our machines.
* ``OPENBLAS_NUM_THREADS=1`` (and OMP/MKL): association works on small matrices, where BLAS
  threads cost far more than they save (an 80x80 triangular solve: 0.09 ms on one thread,
  0.8 ms on two), and runtimes are reported per core. Has no effect if numpy was imported first.
* ``NUMBA_CACHE_DIR``: compiled kernels are cached under the assocbench cache folder, in a
  subfolder named by the digest of this package's sources. numba checks only the timestamp of
  the file that defines a kernel, while a kernel carries compiled copies of the kernels it calls
  from other files (the JCBB search embeds the joint-test math); keying the folder by all
  sources means an upgrade or an edit never runs stale machine code. A cache folder that cannot
  be written sends the kernels to the system's temporary folder instead; ``kernels.install()``
  makes a damaged cache file a recompile rather than a crash.
* ``ASSOCBENCH_CACHE``: an empty value counts as unset; a relative one is made absolute once.
"""

import os
import tempfile
from pathlib import Path

from .fingerprint import package_digest


def cache_root() -> Path:
    """Where assocbench caches things: ``$ASSOCBENCH_CACHE`` or ``~/.cache/assocbench``.
    An empty ``ASSOCBENCH_CACHE`` counts as unset; a relative one is taken from the folder
    the process started in (``_resolve_cache_env`` makes it absolute at import)."""
    value = os.environ.get("ASSOCBENCH_CACHE", "").strip()
    return Path(value).expanduser().absolute() if value else Path.home() / ".cache" / "assocbench"


def _resolve_cache_env() -> None:
    """Empty means unset (it cached into the current folder); a relative path is resolved
    once, here, so a later ``chdir`` or a worker process started elsewhere uses the same folder."""
    if not os.environ.get("ASSOCBENCH_CACHE", "x").strip():
        del os.environ["ASSOCBENCH_CACHE"]
    elif "ASSOCBENCH_CACHE" in os.environ:
        os.environ["ASSOCBENCH_CACHE"] = str(cache_root())


def _numba_cache_dir() -> str:
    """``<cache>/numba/<digest>``, or a folder under the system's temporary folder when the
    cache folder cannot be written: numba would otherwise fall back to ``__pycache__`` next to
    the sources, keyed by file dates only. (Rendering still needs the cache and says so.)"""
    path = cache_root() / "numba" / package_digest()
    try:
        path.mkdir(parents=True, exist_ok=True)
        if os.access(path, os.W_OK):
            return str(path)
    except OSError:
        pass
    user = os.getuid() if hasattr(os, "getuid") else "user"
    return str(Path(tempfile.gettempdir()) / f"assocbench-numba-{user}" / package_digest())


_resolve_cache_env()
os.environ.setdefault("MUJOCO_GL", "egl")
# compiled kernels are cached where a user can always write (site-packages may be read-only)
if "NUMBA_CACHE_DIR" not in os.environ:
    os.environ["NUMBA_CACHE_DIR"] = _numba_cache_dir()
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from . import kernels  # noqa: E402  (after the variables above: it imports numba, hence numpy)

kernels.install()  # a damaged numba cache file is recompiled, not a crash on every run
