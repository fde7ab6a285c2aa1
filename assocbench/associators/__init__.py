"""Associators: one file each, one base class, one registry (``make_associator``)."""

from .base import Associator
from .registry import available, make_associator

__all__ = ["Associator", "available", "make_associator"]
