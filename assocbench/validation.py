"""Checks of user settings: the type from a dataclass field's annotation, the range from its
metadata. Settings sections and associators are dataclasses whose fields declare what they accept::

    sigma_position: float = field(default=0.03, metadata=in_range(0, None))
    occlusion: str = field(default="ray", metadata=one_of("ray", "depth"))

``validate_fields(obj, "belief")`` checks each value when built: a real number (not a string or
bool), finite, integral for ``int``, in range; a string among its choices. A failure is one
``UserError`` line naming the key (``belief.sigma_rotation must be a finite number >= 0, got nan``).
Integers given for floats are stored as floats.
"""

from __future__ import annotations

import dataclasses
import math
import reprlib
import types
import typing
from typing import Any

import yaml

from .errors import UserError

Number = int | float
MAX_YAML_VALUES = 100_000   # values a settings file may expand to through its aliases
_BRIEF = reprlib.Repr()
_BRIEF.maxlevel, _BRIEF.maxlist, _BRIEF.maxdict, _BRIEF.maxstring, _BRIEF.maxother = 3, 6, 6, 60, 60


def brief(value: Any) -> str:
    """``repr(value)`` for a message, at most 80 characters, without walking all of ``value`` (a
    YAML alias bomb expands to 10⁹ items)."""
    text = _BRIEF.repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


class BoundedLoader(yaml.SafeLoader):
    """PyYAML's safe loader refusing a document whose aliases expand to more than
    ``MAX_YAML_VALUES`` values or refer to themselves: ten lines of nested aliases make 10⁹ values
    that every later step would expand."""

    def compose_document(self):
        node = super().compose_document()
        if node is not None and _expanded_size(node, {}, set()) > MAX_YAML_VALUES:
            raise yaml.constructor.ConstructorError(
                None, None, f"its aliases expand to more than {MAX_YAML_VALUES} values; write the values out")
        return node


def _expanded_size(node: yaml.Node, memo: dict, open_nodes: set) -> int:
    """How many values ``node`` stands for with every alias written out (shared nodes counted where
    used, computed once); ``MAX_YAML_VALUES + 1`` for a node containing itself."""
    if id(node) in memo:
        return memo[id(node)]
    if id(node) in open_nodes:
        return MAX_YAML_VALUES + 1
    open_nodes.add(id(node))
    children = [] if isinstance(node, yaml.ScalarNode) else (
        [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode) else node.value)
    size = 1
    for child in children:
        size += _expanded_size(child, memo, open_nodes)
        if size > MAX_YAML_VALUES:
            break
    open_nodes.discard(id(node))
    memo[id(node)] = size
    return size


def in_range(lo: Number | None = None, hi: Number | None = None, *, lo_open: bool = False,
             hi_open: bool = False, unit: str | None = None) -> dict:
    """Field metadata: the value must lie in ``[lo, hi]`` (open ends with ``lo_open``/``hi_open``;
    None: unbounded), in ``unit`` (``"dimensionless"`` for a ratio), which the settings reference
    shows."""
    return {"range": (lo, hi, lo_open, hi_open)} | ({"unit": unit} if unit else {})


def one_of(*choices: str) -> dict:
    """Field metadata: the value must be one of ``choices``."""
    return {"choices": tuple(choices)}


def describe_range(lo, hi, lo_open: bool = False, hi_open: bool = False) -> str:
    """``'>= 0'``, ``'in (0, 1)'``, ``'<= 5000'``: the range in words for an error message."""
    if lo is not None and hi is not None:
        return f"in {'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}"
    if lo is not None:
        return f"{'>' if lo_open else '>='} {lo}"
    if hi is not None:
        return f"{'<' if hi_open else '<='} {hi}"
    return "finite"


INT_LIMIT = 10**15   # an integer setting beyond this cannot be meant, and overflows the kernels' int64


def check_number(value: Any, key: str, *, integer: bool = False, lo=None, hi=None, lo_open: bool = False,
                 hi_open: bool = False) -> Number:
    """``value`` if a finite real number (an integer when ``integer``) in range, else a one-line
    ``UserError`` naming ``key``; bools are refused (``frames: true`` is a mistake)."""
    what = "an integer" if integer else "a finite number"
    where = describe_range(lo, hi, lo_open, hi_open)
    expect = f"{key} must be {what}" + ("" if where == "finite" else f" {where}")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserError(f"{expect}, got {brief(value)}")
    if integer and not isinstance(value, int):
        raise UserError(f"{expect}, got {brief(value)}")
    if integer and abs(value) > INT_LIMIT:   # compiled kernels take 64-bit integers
        raise UserError(f"{expect} of at most {INT_LIMIT:.0e} in size, got {brief(value)}")
    if not math.isfinite(value):
        raise UserError(f"{expect}, got {brief(value)}")
    below = lo is not None and (value <= lo if lo_open else value < lo)
    above = hi is not None and (value >= hi if hi_open else value > hi)
    if below or above:
        raise UserError(f"{expect}, got {brief(value)}")
    return value


def _kinds(annotation) -> tuple[set, bool]:
    """The plain types an annotation admits and whether it admits None (``float | None``)."""
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        args = typing.get_args(annotation)
        return {a for a in args if a is not type(None)}, type(None) in args
    return {annotation}, False


def check_field(value: Any, annotation, metadata, key: str) -> Any:
    """Check one value against its field's annotation and metadata; return it (ints as floats for
    float fields)."""
    kinds, optional = _kinds(annotation)
    if value is None:
        if optional:
            return None
        raise UserError(f"{key} must be set, got null")
    rng = metadata.get("range", (None, None, False, False))
    if kinds & {float, int} and not kinds & {str, bool}:
        integer = int in kinds and float not in kinds
        check_number(value, key, integer=integer, lo=rng[0], hi=rng[1], lo_open=rng[2], hi_open=rng[3])
        return float(value) if not integer else value
    if kinds == {bool} and not isinstance(value, bool):
        raise UserError(f"{key} must be true or false, got {brief(value)}")
    if kinds == {dict} and not isinstance(value, dict):
        raise UserError(f"{key} must be a mapping such as {{name: value}}, got {brief(value)}")
    if kinds == {str}:
        choices = metadata.get("choices")
        if not isinstance(value, str) or (choices and value not in choices):
            hint = f"one of {', '.join(choices)}" if choices else "a string"
            raise UserError(f"{key} must be {hint}, got {brief(value)}")
    return value


def validate_fields(obj: Any, section: str) -> None:
    """Check every field of dataclass instance ``obj`` (keys ``section.field``), storing floats for
    integers given to float fields; unresolvable annotations check numbers for finiteness only."""
    try:
        hints = typing.get_type_hints(type(obj))
    except Exception:  # noqa: BLE001 - a plugin's annotations may name things we cannot import
        hints = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        key = f"{section}.{f.name}" if section else f.name
        if f.name in hints:
            value = check_field(value, hints[f.name], f.metadata, key)
            object.__setattr__(obj, f.name, value)
        elif isinstance(value, float) and not math.isfinite(value):
            raise UserError(f"{key} must be a finite number, got {brief(value)}")


def typed_section(cls, values: dict, section: str):
    """``cls(**values)`` with every field checked; a one-line ``UserError`` naming ``section`` for a
    non-mapping or bad value."""
    if not isinstance(values, dict):
        raise UserError(f"{section} must be a mapping of settings, got {brief(values)}")
    try:
        return cls(**values)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, UserError):
            raise
        raise UserError(f"bad value in {section}: {exc}") from None


def free_mapping(cfg: dict, key: str) -> dict:
    """A free-form section (``params``, ``trajectory_params``): a mapping whose numbers are finite."""
    value = cfg[key] if cfg[key] is not None else {}
    if not isinstance(value, dict):
        raise UserError(f"{key} must be a mapping such as {{name: value}}, got {brief(value)}")
    for name, item in value.items():
        if isinstance(item, float):
            check_number(item, f"{key}.{name}")
    return dict(value)
