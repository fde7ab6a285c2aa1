"""assocbench: a reproducible benchmark for data association in SLAM and tracking.

Public API::

    from assocbench import Problem, make_associator
    association = make_associator("jcbb").associate(problem)
"""

# first: _load_times notes when each later module is loaded; _runtime sets MUJOCO_GL=egl and
# single-thread BLAS, unless the user chose
from . import _load_times, _runtime  # noqa: F401
from .association.compatibility import jointly_compatible, surprisal
from .association.problem import Problem, validate_association
from .associators import Associator, available, make_associator
from .errors import UserError

__all__ = [
    "Associator", "Problem", "UserError", "available", "jointly_compatible", "make_associator",
    "surprisal", "validate_association",
]
__version__ = "0.1.0"
# The Gymnasium environments register when ``assocbench.gymenv`` is imported (or through
# ``gym.make("assocbench.gymenv:assocbench/Room-v0")``), not here: the contract above must load
# without the simulator, OpenCV, Gymnasium or the harness.
