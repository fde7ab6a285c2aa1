"""Process defaults applied before numpy or mujoco load (each only if the user set nothing):

* ``MUJOCO_GL=egl``: EGL renders headless.
* ``OPENBLAS_NUM_THREADS=1`` (and OMP/MKL): association works on small matrices, where BLAS threads
  cost more than they save, and runtimes are reported per core. No effect if numpy was imported
  first.
* ``NUMBA_CACHE_DIR``: kernels are cached under the assocbench cache folder in a subfolder named by
  the digest of the package's sources: numba checks only the defining file's timestamp, while a
  kernel embeds compiled copies of kernels from other files, so keying by all sources never runs
  stale machine code. An unwritable folder sends the kernels to the temporary folder;
  ``kernels.install()`` makes a damaged cache file a recompile.
* ``ASSOCBENCH_CACHE``: empty counts as unset; a relative one is made absolute once.
"""

import os
import tempfile
from pathlib import Path

from .fingerprint import package_digest


def cache_root() -> Path:
    """Where assocbench caches things: ``$ASSOCBENCH_CACHE`` (empty: unset; relative: from the start
    folder) or ``~/.cache/assocbench``."""
    value = os.environ.get("ASSOCBENCH_CACHE", "").strip()
    return Path(value).expanduser().absolute() if value else Path.home() / ".cache" / "assocbench"


def _resolve_cache_env() -> None:
    """Empty means unset; a relative path is resolved once, so a later ``chdir`` or a worker started
    elsewhere uses the same folder."""
    if not os.environ.get("ASSOCBENCH_CACHE", "x").strip():
        del os.environ["ASSOCBENCH_CACHE"]
    elif "ASSOCBENCH_CACHE" in os.environ:
        os.environ["ASSOCBENCH_CACHE"] = str(cache_root())


def _numba_cache_dir() -> str:
    """``<cache>/numba/<digest>``, or a temporary folder when the cache cannot be written (numba
    would fall back to ``__pycache__`` keyed by file dates only)."""
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
