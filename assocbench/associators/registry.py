"""Registry of associators: the six built-ins, entry-point plugins and ``pkg.module:Class`` specs."""

from __future__ import annotations

import difflib
import importlib
from dataclasses import fields
from importlib.metadata import entry_points

from ..errors import UserError
from .base import Associator
from .enn import ENN
from .jcbb import JCBB
from .lsa import LSA
from .ml import ML
from .mnn import MNN
from .snn import SNN

ENTRY_POINT_GROUP = "assocbench.associators"
BUILTINS: dict[str, type[Associator]] = {cls.name: cls for cls in (ENN, MNN, ML, SNN, JCBB, LSA)}


def _load_spec(spec: str) -> type[Associator]:
    module_name, _, attr = spec.partition(":")
    try:
        obj = getattr(importlib.import_module(module_name), attr)
    except (ImportError, AttributeError) as exc:
        raise UserError(f"cannot load associator {spec!r}: {exc}") from None
    if not (isinstance(obj, type) and callable(getattr(obj, "associate", None))):
        raise UserError(f"{spec!r} is not an associator class with an associate(problem) method")
    return obj


def plugins() -> dict[str, str]:
    """Associators installed by other packages: name -> ``module:Class``."""
    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available() -> dict[str, str]:
    """Every associator name usable with ``make_associator``, with its one-line summary."""
    out = {name: cls.summary for name, cls in BUILTINS.items()}
    for name, value in plugins().items():
        out.setdefault(name, f"plugin {value}")
    return out


def associator_class(method: str) -> type[Associator]:
    """Class of a built-in name, a plugin name or a ``pkg.module:Class`` spec."""
    key = method.lower()
    if key in BUILTINS:
        return BUILTINS[key]
    if method in plugins():
        return _load_spec(plugins()[method])
    if ":" in method:
        return _load_spec(method)
    close = difflib.get_close_matches(key, list(available()), n=3, cutoff=0.4)
    hint = f"did you mean {', '.join(close)}? " if close else ""
    raise UserError(f"unknown method {method!r}: {hint}choose one of {', '.join(available())} or pkg.module:Class")


def make_associator(method: str, **params) -> Associator:
    """An associator instance: ``make_associator("jcbb", confidence=0.95).associate(problem)``."""
    cls = associator_class(method)
    try:
        return cls(**params)
    except TypeError:
        allowed = [f.name for f in fields(cls)] if hasattr(cls, "__dataclass_fields__") else []
        unknown = sorted(set(params) - set(allowed)) or sorted(params)
        raise UserError(
            f"unknown parameter {', '.join(unknown)} for method {method!r}: accepted are {', '.join(allowed) or 'none'}"
        ) from None
