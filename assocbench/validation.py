"""Checks of user settings: the type from a dataclass field's annotation, the range from its metadata.

Every stage's settings (``BeliefConfig``, ``DetectorConfig``, ``TruthConfig``) and every
associator are dataclasses; a field declares what it accepts::

    sigma_position: float = field(default=0.03, metadata=in_range(0, None))
    occlusion: str = field(default="ray", metadata=one_of("ray", "depth"))

and ``validate_fields(obj, "belief")`` checks each value when the object is built: a number must
be a real number (not a string, not a bool), finite, integral where the annotation says ``int``,
and inside its range; a string must be one of its choices. A failure is one ``UserError`` line
naming the key (``belief.sigma_rotation must be a finite number >= 0, got nan``). Integers
given for float fields are stored as floats, so ``1`` and ``1.0`` mean one setting.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from typing import Any

from .errors import UserError

Number = int | float


def in_range(lo: Number | None = None, hi: Number | None = None, *, lo_open: bool = False,
             hi_open: bool = False, unit: str | None = None) -> dict:
    """Field metadata: the value must lie in ``[lo, hi]`` (``(`` / ``)`` where open; None: unbounded),
    in ``unit`` (``"m"``, ``"deg"``; ``"dimensionless"`` for a ratio or a share), which the settings
    reference shows."""
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
    """``value`` if it is a finite real number (an integer when ``integer``) inside the range, else a
    one-line ``UserError`` naming ``key``. Bools are refused: ``frames: true`` is a mistake."""
    what = "an integer" if integer else "a finite number"
    where = describe_range(lo, hi, lo_open, hi_open)
    expect = f"{key} must be {what}" + ("" if where == "finite" else f" {where}")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserError(f"{expect}, got {value!r}")
    if integer and not isinstance(value, int):
        raise UserError(f"{expect}, got {value!r}")
    if integer and abs(value) > INT_LIMIT:   # compiled kernels take 64-bit integers
        raise UserError(f"{expect} of at most {INT_LIMIT:.0e} in size, got {value!r}")
    if not math.isfinite(value):
        raise UserError(f"{expect}, got {value!r}")
    below = lo is not None and (value <= lo if lo_open else value < lo)
    above = hi is not None and (value >= hi if hi_open else value > hi)
    if below or above:
        raise UserError(f"{expect}, got {value!r}")
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
        raise UserError(f"{key} must be true or false, got {value!r}")
    if kinds == {str}:
        choices = metadata.get("choices")
        if not isinstance(value, str) or (choices and value not in choices):
            hint = f"one of {', '.join(choices)}" if choices else "a string"
            raise UserError(f"{key} must be {hint}, got {value!r}")
    return value


def validate_fields(obj: Any, section: str) -> None:
    """Check every field of dataclass instance ``obj`` (keys named ``section.field``); store floats
    for integers given to float fields. Fields whose annotation cannot be resolved are checked
    for finiteness only when they hold a number."""
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
            raise UserError(f"{key} must be a finite number, got {value!r}")


def typed_section(cls, values: dict, section: str):
    """``cls(**values)``: a settings section built from its mapping, every field checked; a
    one-line ``UserError`` naming ``section`` for a non-mapping or a bad value."""
    if not isinstance(values, dict):
        raise UserError(f"{section} must be a mapping of settings, got {values!r}")
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
        raise UserError(f"{key} must be a mapping such as {{name: value}}, got {value!r}")
    for name, item in value.items():
        if isinstance(item, float):
            check_number(item, f"{key}.{name}")
    return dict(value)
