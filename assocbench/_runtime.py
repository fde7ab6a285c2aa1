"""Process defaults applied before numpy or mujoco load (each only if the user set nothing).

* ``MUJOCO_GL=egl``: EGL renders headless; osmesa and glfw do not on our machines.
* ``OPENBLAS_NUM_THREADS=1`` (and OMP/MKL): association works on small matrices, where BLAS
  threads cost far more than they save (an 80x80 triangular solve: 0.09 ms on one thread,
  0.8 ms on two), and runtimes are reported per core. Has no effect if numpy was imported first.
* ``NUMBA_CACHE_DIR``: compiled kernels are cached under the assocbench cache folder, in a
  subfolder named by the digest of this package's sources. numba checks only the timestamp of
  the file that defines a kernel, while a kernel carries compiled copies of the kernels it calls
  from other files (the JCBB search embeds the joint-test math); keying the folder by all
  sources means an upgrade or an edit never runs stale machine code.
"""

import os
from pathlib import Path

from .fingerprint import package_digest


def cache_root() -> Path:
    """Where assocbench caches things: ``$ASSOCBENCH_CACHE`` or ``~/.cache/assocbench``."""
    return Path(os.environ.get("ASSOCBENCH_CACHE", Path.home() / ".cache" / "assocbench"))


os.environ.setdefault("MUJOCO_GL", "egl")
# compiled kernels are cached where a user can always write (site-packages may be read-only)
os.environ.setdefault("NUMBA_CACHE_DIR", str(cache_root() / "numba" / package_digest()))
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
