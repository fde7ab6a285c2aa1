"""The dense associators by name: ``make_dense_associator("projective", d_thr=0.03)``.

Separate from the sparse registry (``associators.registry``): a dense associator pairs source
points with pixels (``associate(points, normals, frame, R, t) -> Pairs``), not candidates with
features, so the two are never interchangeable.
"""

from __future__ import annotations

import difflib
from dataclasses import fields

from ...errors import UserError
from .base import DenseAssociator
from .kdtree import KdTreeAssociator
from .projective import ProjectiveAssociator

DENSE_METHODS: dict[str, type[DenseAssociator]] = {
    cls.name: cls for cls in (ProjectiveAssociator, KdTreeAssociator)}


def make_dense_associator(name: str, **params) -> DenseAssociator:
    """A dense associator; a one-line ``UserError`` for an unknown name, an unknown parameter or
    a bad value (``params.d_thr must be a finite number > 0, got 0``)."""
    cls = DENSE_METHODS.get(str(name).lower())
    if cls is None:
        close = difflib.get_close_matches(str(name).lower(), list(DENSE_METHODS), n=2, cutoff=0.4)
        hint = f"did you mean {', '.join(close)}? " if close else ""
        raise UserError(f"unknown dense method {name!r}: {hint}choose one of {', '.join(DENSE_METHODS)}")
    allowed = [f.name for f in fields(cls)]
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise UserError(f"unknown parameter {', '.join(unknown)} for dense method {name!r}: "
                        f"accepted are {', '.join(allowed)}")
    return cls(**params)
