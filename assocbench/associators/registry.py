"""Registry of associators: the built-ins, entry-point plugins and ``pkg.module:Class`` specs.
Feature associators (``Associator``) and dense ones (``dense.DenseAssociator``; ``dense.is_dense``,
``dense.make_dense_associator``) share it; a method's kind implies its track, so a user's dense
associator plugs in like a feature one.

Built-ins are lazy ``module:Class`` strings, as the track registry's: asking for one imports its
module alone (and what that module imports), so a stored run's inputs (``harness/inputs.py``) name
its method's files and no other method's, and editing one method recomputes only its runs.
"""

from __future__ import annotations

import difflib
import importlib
from dataclasses import fields, is_dataclass
from importlib.metadata import entry_points

from ..errors import UserError
from ..validation import brief, validate_fields
from .base import Associator

ENTRY_POINT_GROUP = "assocbench.associators"
BUILTINS: dict[str, str] = {   # feature associators: name -> "module:Class"
    "enn": "assocbench.associators.enn:ENN",
    "mnn": "assocbench.associators.mnn:MNN",
    "ml": "assocbench.associators.ml:ML",
    "snn": "assocbench.associators.snn:SNN",
    "jcbb": "assocbench.associators.jcbb:JCBB",
    "lsa": "assocbench.associators.lsa:LSA",
    "rjc": "assocbench.associators.rjc:RJC",
    "ccda": "assocbench.associators.ccda:CCDA",
    "jpda": "assocbench.associators.jpda:JPDA",
    "naive": "assocbench.associators.naive:Naive",
    "learned": "assocbench.associators.learned.associator:Learned",
    "appearance": "assocbench.associators.appearance:Appearance",
}
DENSE_BUILTINS: dict[str, str] = {   # the dense track's associators
    "projective": "assocbench.associators.dense.projective:ProjectiveAssociator",
    "kdtree": "assocbench.associators.dense.kdtree:KdTreeAssociator",
}
ALL_BUILTINS: dict[str, str] = {**BUILTINS, **DENSE_BUILTINS}


def builtin_class(name: str) -> type:
    """The class of the built-in ``name`` (a key of ``ALL_BUILTINS``), importing its module now.
    Imported on every ask (a no-op once loaded) so a worker's import log sees which method asked."""
    module, _, attr = ALL_BUILTINS[name].partition(":")
    return getattr(importlib.import_module(module), attr)


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


def geometric_builtins() -> list[str]:
    """The built-in feature associators that need nothing but geometry: all but those that need
    descriptors (``needs_descriptors``: appearance, which only the photos track feeds)."""
    return [name for name in BUILTINS if not getattr(builtin_class(name), "needs_descriptors", False)]


def names() -> list[str]:
    """Every associator name usable with ``make_associator``, built-ins first, importing none."""
    return list(dict.fromkeys([*ALL_BUILTINS, *plugins()]))


def available() -> dict[str, str]:
    """Every associator name usable with ``make_associator``, with its one-line summary (this
    imports every built-in and plugin: ``names`` lists them without)."""
    out = {name: builtin_class(name).summary for name in ALL_BUILTINS}
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
        return builtin_class(key)
    if method in plugins():
        return _load_spec(plugins()[method])
    if ":" in method:
        return _load_spec(method)
    close = difflib.get_close_matches(key, names(), n=3, cutoff=0.4)
    hint = f"did you mean {', '.join(close)}? " if close else ""
    raise UserError(f"unknown method {method!r}: {hint}choose one of {', '.join(names())} or pkg.module:Class")


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

