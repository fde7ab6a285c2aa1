"""Shipped YAML configs and suites, installed as ``assocbench.configs``."""

from importlib import resources
from pathlib import Path


def shipped_config(name: str) -> Path:
    """Path of a YAML shipped in ``assocbench/configs`` (``ci.yaml``, ``planar.yaml``...)."""
    return Path(str(resources.files("assocbench.configs"))) / name
