"""Settings files: YAML read safely (duplicate keys refused, ``1e-3`` read as a number) and
``--set key=value`` overrides parsed the same way; the shipped configs' folder."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from ..errors import UserError
from ..validation import BoundedLoader


class _UniqueKeyLoader(BoundedLoader):
    """A safe YAML loader refusing a key given twice in a mapping (YAML keeps the last silently) and
    alias bombs (``BoundedLoader``)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}: give each key once", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


# YAML 1.1 (PyYAML) reads 5e-1 or 1e-3 as strings: it wants a dot and a signed exponent. Floats
# people type in settings are read as floats here, in files and in --set alike.
_FLOAT = re.compile(r"""^[-+]?(?:[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                    |[0-9][0-9_]*[eE][-+]?[0-9]+
                    |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                    |\.(?:inf|Inf|INF))$|^\.(?:nan|NaN|NAN)$""", re.X)
_UniqueKeyLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT, list("-+0123456789."))


def read_yaml(path: str | Path) -> dict:
    """Parse a YAML mapping, or raise a one-line ``UserError`` (duplicate keys included)."""
    path = Path(path)
    if path.is_dir():
        raise UserError(f"config file {path} is a folder; pass a YAML file")
    if not path.is_file():
        raise UserError(f"config file {path} not found; pass an existing YAML file")
    try:
        data = yaml.load(path.read_text(), Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader
    except UnicodeDecodeError:
        raise UserError(f"{path} is not a text YAML file") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise UserError(f"malformed YAML in {path}{where}: {getattr(exc, 'problem', exc)}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise UserError(f"{path} must hold a mapping of keys to values, got {type(data).__name__}")
    return data


def parse_sets(items: list[str] | None) -> dict:
    """``["belief.clutter=5", "frames=10"]`` -> nested mapping (values parsed as YAML)."""
    out: dict = {}
    for item in items or []:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set expects key=value, got {item!r}")
        try:
            value = yaml.load(raw, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader
        except yaml.YAMLError:
            value = raw
        node = out
        parts = key.strip().split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return out
