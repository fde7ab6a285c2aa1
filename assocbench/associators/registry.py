"""Registry of associators: the built-ins, entry-point plugins and ``pkg.module:Class`` specs.
Feature associators (``Associator``) and dense ones (``dense.DenseAssociator``) share it; a method's
kind implies its track, so a user's dense associator plugs in like a feature one."""

from __future__ import annotations

import difflib
import importlib
from dataclasses import fields, is_dataclass
from importlib.metadata import entry_points

from ..errors import UserError
from ..validation import brief, validate_fields
from .appearance import Appearance
from .base import Associator
from .ccda import CCDA
from .dense import DENSE_METHODS, DenseAssociator
from .enn import ENN
from .jcbb import JCBB
from .jpda import JPDA
from .learned import Learned
from .lsa import LSA
from .ml import ML
from .mnn import MNN
from .naive import Naive
from .rjc import RJC
from .snn import SNN

ENTRY_POINT_GROUP = "assocbench.associators"
BUILTINS: dict[str, type[Associator]] = {cls.name: cls for cls in (ENN, MNN, ML, SNN, JCBB, LSA, RJC, CCDA, JPDA, Naive, Learned,
                                                                    Appearance)}
ALL_BUILTINS: dict[str, type] = {**BUILTINS, **DENSE_METHODS}


def _load_spec(spec: str) -> type[Associator]:
    module_name, _, attr = spec.partition(":")
    try:
        obj = getattr(importlib.import_module(module_name), attr)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - a plugin that fails to import (SyntaxError, raises, exits)
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise UserError(f"cannot load associator {spec!r}: {type(exc).__name__}"
                        f"{': ' + detail if detail else ''}") from None
    if not (isinstance(obj, type) and callable(getattr(obj, "associate", None))):
        raise UserError(f"{spec!r} is not an associator class with an associate(problem) method")
    return obj


def plugins() -> dict[str, str]:
    """Associators installed by other packages: name -> ``module:Class``."""
    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available() -> dict[str, str]:
    """Every associator name usable with ``make_associator``, with its one-line summary."""
    out = {name: cls.summary for name, cls in ALL_BUILTINS.items()}
    for name, value in plugins().items():
        out.setdefault(name, _plugin_summary(value))
    return out


def _plugin_summary(spec: str) -> str:
    """A plugin's ``summary`` (else its docstring's first line) and where it comes from; a plugin
    that does not load says why instead."""
    try:
        cls = _load_spec(spec)
    except UserError as exc:
        return f"(plugin {spec}: {exc})"
    text = getattr(cls, "summary", "") or " ".join((cls.__doc__ or "").strip().split("\n\n")[0].split())
    return f"{text} (plugin {spec})" if text else f"plugin {spec}"


def associator_class(method: str) -> type[Associator]:
    """Class of a built-in name, a plugin name or a ``pkg.module:Class`` spec."""
    key = method.lower()
    if key in ALL_BUILTINS:
        return ALL_BUILTINS[key]
    if method in plugins():
        return _load_spec(plugins()[method])
    if ":" in method:
        return _load_spec(method)
    close = difflib.get_close_matches(key, list(available()), n=3, cutoff=0.4)
    hint = f"did you mean {', '.join(close)}? " if close else ""
    raise UserError(f"unknown method {method!r}: {hint}choose one of {', '.join(available())} or pkg.module:Class")


def make_associator(method: str, **params) -> Associator:
    """An associator instance: ``make_associator("jcbb", confidence=0.95).associate(problem)``.
    Parameters are checked here, before anything runs: unknown names, and each dataclass field's
    type and range (``validation.validate_fields``)."""
    cls = associator_class(method)
    allowed = [f.name for f in fields(cls)] if is_dataclass(cls) else None
    unknown = sorted(set(params) - set(allowed)) if allowed is not None else []
    if unknown:
        raise UserError(f"unknown parameter {', '.join(unknown)} for method {method!r}: "
                        f"accepted are {', '.join(allowed) or 'none'}")
    try:
        associator = cls(**params)
    except UserError:
        raise
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - a plugin's constructor is user code
        raise UserError(f"cannot build method {method!r} with parameters {brief(params)}: {type(exc).__name__}: {exc}") from None
    if allowed is not None and not isinstance(associator, Associator):
        validate_fields(associator, "params")   # Associator subclasses check themselves
    return associator


def is_dense(method: str) -> bool:
    """Whether ``method`` resolves to a dense associator (False when it does not resolve)."""
    try:
        return issubclass(associator_class(method), DenseAssociator)
    except UserError:
        return False


def make_dense_associator(method: str, **params) -> DenseAssociator:
    """A dense associator (``make_associator``), or a one-line error when ``method`` is not one."""
    associator = make_associator(method, **params)
    if not isinstance(associator, DenseAssociator):
        raise UserError(f"method {method!r} is not a dense associator (subclass "
                        "assocbench.associators.dense.DenseAssociator); a feature associator runs on the "
                        "camera, planar or lines track")
    return associator
