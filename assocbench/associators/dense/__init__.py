"""Dense associators: source points (world) paired with pixels of a depth frame.

``make_dense_associator(name, **params).associate(points, normals, frame, R, t) -> Pairs``;
``DENSE_METHODS`` lists them (``projective``, ``kdtree``); ``warm_dense()`` loads or compiles
the dense kernels (association and ICP) once per process.
"""

from .base import DenseAssociator, Pairs
from .registry import DENSE_METHODS, make_dense_associator
from ...tracks.dense.warm import warm_dense

__all__ = ["DENSE_METHODS", "DenseAssociator", "Pairs", "make_dense_associator", "warm_dense"]
