"""Dense associators: source points (world) paired with pixels of a depth frame.

``make_dense_associator(name, **params).associate(points, normals, frame, R, t) -> Pairs``;
``DENSE_METHODS`` lists the built-ins (``projective``, ``kdtree``); they are registered with the
other associators (``associators.registry``), so ``--method pkg.module:Class`` plugs in a user's
``DenseAssociator`` the same way, and the method implies the dense track.
"""

from .base import DenseAssociator, Pairs
from .kdtree import KdTreeAssociator
from .projective import ProjectiveAssociator

DENSE_METHODS: dict[str, type[DenseAssociator]] = {
    cls.name: cls for cls in (ProjectiveAssociator, KdTreeAssociator)}

__all__ = ["DENSE_METHODS", "DenseAssociator", "Pairs"]
