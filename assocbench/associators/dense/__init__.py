"""Dense associators: source points (world) paired with pixels of a depth frame.
``make_dense_associator(name, **params).associate(points, normals, frame, R, t) -> Pairs``; the
built-ins (``projective``, ``kdtree``: ``registry.DENSE_BUILTINS``) are registered with the other
associators, so ``--method pkg.module:Class`` plugs in a user's ``DenseAssociator`` too. Neither is
imported here: a run imports only its own method's module.
"""

from ...errors import UserError
from ..registry import associator_class, make_associator
from .base import DenseAssociator, Pairs


def is_dense(method: str) -> bool:
    """Whether ``method`` resolves to a dense associator (False when it does not resolve)."""
    try:
        return issubclass(associator_class(method), DenseAssociator)
    except UserError:
        return False


def make_dense_associator(method: str, **params) -> DenseAssociator:
    """A dense associator (``registry.make_associator``), or a one-line error when ``method`` is not one."""
    associator = make_associator(method, **params)
    if not isinstance(associator, DenseAssociator):
        raise UserError(f"method {method!r} is not a dense associator (subclass "
                        "assocbench.associators.dense.DenseAssociator); a feature associator runs on the "
                        "camera, planar or lines track")
    return associator


__all__ = ["DenseAssociator", "Pairs", "is_dense", "make_dense_associator"]
