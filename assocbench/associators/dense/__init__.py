"""Dense associators: source points (world) paired with pixels of a depth frame.
``make_dense_associator(name, **params).associate(points, normals, frame, R, t) -> Pairs``; the
built-ins (``DENSE_METHODS``: ``projective``, ``kdtree``) are registered with the other associators,
so ``--method pkg.module:Class`` plugs in a user's ``DenseAssociator`` too.
"""

from .base import DenseAssociator, Pairs
from .kdtree import KdTreeAssociator
from .projective import ProjectiveAssociator

DENSE_METHODS: dict[str, type[DenseAssociator]] = {
    cls.name: cls for cls in (ProjectiveAssociator, KdTreeAssociator)}

__all__ = ["DENSE_METHODS", "DenseAssociator", "Pairs"]
