"""A track's settings: one schema of top-level keys and sections, its defaults, and the typed values
built from a run config, every value checked once. Fields declare what they accept (``validation``;
a ``check()`` for rules across fields):

* ``keys``: dataclasses whose fields are top-level keys (``frames``, ``trajectory``);
* ``sections``: ``name -> Section(cls)``, a nested mapping (``belief: {clutter: 5}``); fields a
  track does not use are named in ``exclude``, refused in its runs and left at their defaults.

``Schema.defaults()`` is where a run config starts; ``Schema.build(cfg)`` makes ``Settings``
(``settings.belief.clutter``), checking each value and each section's ``check()`` once. Unknown keys
are refused earlier, when merging (``harness.config``).
"""

from __future__ import annotations

import copy
import dataclasses
import re
import typing
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from .errors import UserError
from .validation import check_field, describe_range, typed_section


@dataclass(frozen=True)
class Section:
    """A nested settings section: the dataclass ``cls`` less the fields in ``exclude``."""

    cls: type
    exclude: tuple[str, ...] = ()

    def fields(self) -> list[dataclasses.Field]:
        """The fields this section offers."""
        return [f for f in dataclasses.fields(self.cls) if f.name not in self.exclude]

    def defaults(self) -> dict:
        """``{field: default}`` of the offered fields."""
        instance = self.cls()
        return {f.name: copy.deepcopy(getattr(instance, f.name)) for f in self.fields()}

    def build(self, values: dict, name: str) -> Any:
        """The typed section from its mapping (checked when built, then by its ``check()``)."""
        section = typed_section(self.cls, values, name)
        if callable(getattr(section, "check", None)):
            section.check()
        return section


@dataclass(frozen=True)
class Schema:
    """Top-level keys (the fields of each dataclass in ``keys``) and ``sections``."""

    keys: tuple[type, ...] = ()
    sections: Mapping[str, Section] = field(default_factory=dict)

    def __add__(self, other: Schema) -> Schema:
        """Both schemas' keys and sections; a name in both is a one-line ``UserError``."""
        both = set(self.key_fields()) & set(other.key_fields()) | set(self.sections) & set(other.sections)
        if both:
            raise UserError(f"settings {', '.join(sorted(both))} are declared twice: a track's settings must not "
                            "reuse the names of the common ones (track, scene, frames, seed, method, ...)")
        return Schema(self.keys + other.keys, {**self.sections, **other.sections})

    def key_fields(self) -> dict[str, tuple[type, dataclasses.Field]]:
        """``{key: (dataclass, field)}`` of every top-level key."""
        return {f.name: (cls, f) for cls in self.keys for f in dataclasses.fields(cls)}

    def defaults(self) -> dict:
        """The nested mapping a run config starts from."""
        out = {}
        for cls in self.keys:
            instance = cls()
            out |= {f.name: copy.deepcopy(getattr(instance, f.name)) for f in dataclasses.fields(cls)}
        return out | {name: section.defaults() for name, section in self.sections.items()}

    def build(self, cfg: dict) -> Settings:
        """Typed, checked values of a merged config (``defaults()`` merged with the user's): each
        key by its field, then the dataclass's ``check()``."""
        values: dict[str, Any] = {}
        for cls in self.keys:
            hints = _hints(cls)
            for f in dataclasses.fields(cls):
                values[f.name] = check_field(cfg[f.name], hints.get(f.name, Any), f.metadata, f.name) \
                    if f.name in hints else cfg[f.name]
            group = cls(**{f.name: values[f.name] for f in dataclasses.fields(cls)})
            if callable(getattr(group, "check", None)):
                group.check()
            values |= {f.name: getattr(group, f.name) for f in dataclasses.fields(cls)}
        for name, section in self.sections.items():
            values[name] = section.build(cfg[name], name)
        return Settings(values)

    def describe(self) -> Iterator[Described]:
        """Each setting for the settings reference (``Described``), top-level keys first."""
        for cls in self.keys:
            instance = cls()
            for f in dataclasses.fields(cls):
                yield _described(f.name, instance, cls, f)
        for name, section in self.sections.items():
            instance = section.cls()
            for f in section.fields():
                yield _described(f"{name}.{f.name}", instance, section.cls, f)


class Described(NamedTuple):
    """One setting as the settings reference gives it: ``accepts`` (range, choices or type in words)
    and ``unit`` (``in_range(unit=...)``, "" otherwise)."""

    key: str
    default: Any
    accepts: str
    unit: str
    doc: str
    kind: Any   # the field's annotation (``int``, ``float | None``, ``str``)


def _described(key: str, instance: Any, cls: type, f: dataclasses.Field) -> Described:
    return Described(key, getattr(instance, f.name), accepts(cls, f), f.metadata.get("unit", ""),
                     field_docs(cls).get(f.name, ""), _hints(cls).get(f.name, Any))


class Settings(Mapping):
    """A run's typed settings: top-level values and sections by attribute or by key; read-only."""

    def __init__(self, values: dict) -> None:
        object.__setattr__(self, "_values", dict(values))

    def __getattr__(self, name: str) -> Any:
        try:
            return self.__dict__["_values"][name]
        except KeyError:
            raise AttributeError(f"this run has no setting {name!r}") from None

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("settings are read-only")

    def __getitem__(self, name: str) -> Any:
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __getstate__(self) -> dict:
        return self._values

    def __setstate__(self, state: dict) -> None:
        object.__setattr__(self, "_values", state)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Settings) and self._values == other._values

    def __hash__(self) -> int:
        return hash(tuple(sorted(self._values)))

    def __repr__(self) -> str:
        return f"Settings({', '.join(self._values)})"


def _hints(cls: type) -> dict:
    try:
        return typing.get_type_hints(cls)
    except Exception:  # noqa: BLE001 - a plugin's annotations may name what we cannot import
        return {}


def accepts(cls: type, f: dataclasses.Field) -> str:
    """What a field accepts, in words: its range, its choices, or its type."""
    if "range" in f.metadata:
        lo, hi, lo_open, hi_open = f.metadata["range"]
        hint = _hints(cls).get(f.name)
        kinds = set(typing.get_args(hint)) or {hint}
        kind = "integer" if int in kinds and float not in kinds else "number"
        return ("null or " if type(None) in kinds else "") + f"{kind} {describe_range(lo, hi, lo_open, hi_open)}"
    if "choices" in f.metadata:
        return "one of " + ", ".join(f.metadata["choices"])
    if "accepts" in f.metadata:
        return f.metadata["accepts"]
    hint = _hints(cls).get(f.name)
    return {bool: "true or false", str: "a string", dict: "a mapping"}.get(hint, str(hint or "any").replace("typing.", ""))


def field_docs(cls: type) -> dict[str, str]:
    """``{field: meaning}`` from the class docstring's ``name: text`` entries
    (``sigma_position: camera position std (m).``; ``a / b: text`` names two fields) or a field's
    ``doc`` metadata; a field named nowhere is absent."""
    doc = cls.__doc__ or ""
    names = [f.name for f in dataclasses.fields(cls)]
    hits = sorted((m.start(), m.end(), name) for name in names
                  for m in re.finditer(rf"(?<![\w.`]){re.escape(name)}(?:\s*/\s*\w+)*: ", doc))
    out = {}
    for _, end, name in hits:
        stop = min((start for start, _, _ in hits if start >= end), default=len(doc))
        out.setdefault(name, " ".join(re.split(r"\n\s*\n", doc[end:stop])[0].split()))
    return out | {f.name: f.metadata["doc"] for f in dataclasses.fields(cls) if "doc" in f.metadata}
