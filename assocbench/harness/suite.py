"""Suites: scenes × difficulties × methods × seeds, read from YAML (``configs/leaderboard.yaml``).

A suite file has the keys ``base`` (a run config applied to every run), ``scenes``,
``difficulties`` (name -> run-config overrides, e.g. ``{belief: {sigma_rotation: 2}}``),
``methods`` (names, or mappings ``{name, method, params}`` so a label can point at a plugin),
``seeds``, and optionally ``tolerance`` (for ``check``) and ``description``.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

from ..associators.registry import associator_class
from ..errors import UserError
from ..fingerprint import class_digest, package_digest
from .config import DEFAULTS, merge, read_yaml, run_spec

SUITE_KEYS = ("description", "base", "scenes", "difficulties", "methods", "seeds", "tolerance")


@dataclass(frozen=True)
class MethodEntry:
    """A leaderboard row label and the associator (name or ``pkg.module:Class``) behind it."""

    label: str
    method: str
    params: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Job:
    """Everything run on one rendered sequence: all difficulties and methods for a scene and seed."""

    scene: str
    seed: int
    runs: tuple  # ((difficulty, run config), ...)
    methods: tuple[MethodEntry, ...]

    @property
    def key(self) -> str:
        """Hash of the job's settings and of the code that runs it (this package and each method's
        source file), so results stored by other code are never reused."""
        code = [package_digest()] + [_method_digest(m.method) for m in self.methods]
        payload = json.dumps([self.scene, self.seed, self.runs, [vars(m) for m in self.methods], code],
                             sort_keys=True, default=str)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]


def _method_digest(method: str) -> str:
    """Digest of the file defining a method's class; the name alone when it does not resolve (the
    job then records the error)."""
    try:
        return class_digest(associator_class(method))
    except Exception:  # noqa: BLE001 - a broken plugin must not stop the sweep from being planned
        return method


@dataclass(frozen=True)
class Suite:
    name: str
    jobs: tuple[Job, ...]
    tolerance: float


def _methods(raw, where: str) -> tuple[MethodEntry, ...]:
    if not isinstance(raw, list) or not raw:
        raise UserError(f"'methods' in {where} must be a non-empty list")
    out = []
    for item in raw:
        if isinstance(item, str):
            out.append(MethodEntry(item, item))
        elif isinstance(item, dict) and set(item) <= {"name", "method", "params"} and "method" in item:
            out.append(MethodEntry(str(item.get("name", item["method"])), str(item["method"]), dict(item.get("params") or {})))
        else:
            raise UserError(f"bad method entry {item!r} in {where}: use a name or {{name, method, params}}")
    return tuple(out)


def load_suite(path: str | Path) -> Suite:
    """Read and check a suite file; every run config is resolved now, so errors come early."""
    path = Path(path)
    raw = read_yaml(path)
    for key in raw:
        if key not in SUITE_KEYS:
            raise UserError(f"unknown key {key!r} in {path}; known keys: {', '.join(SUITE_KEYS)}")
    base = merge(DEFAULTS, raw.get("base") or {}, f"{path} base")
    scenes = raw.get("scenes") or [base["scene"]]
    difficulties = raw.get("difficulties") or {"default": {}}
    seeds = raw.get("seeds") or [base["seed"]]
    if not isinstance(difficulties, dict):
        raise UserError(f"'difficulties' in {path} must map names to run-config overrides")
    if not (isinstance(seeds, list) and all(isinstance(s, int) and s >= 0 for s in seeds)):
        raise UserError(f"'seeds' in {path} must be a list of non-negative integers")
    methods = _methods(raw.get("methods"), str(path))
    jobs = []
    for scene in scenes:
        for seed in seeds:
            runs = []
            for name, override in difficulties.items():
                cfg = merge(merge(base, override or {}, f"{path} difficulty {name}"),
                            {"scene": scene, "seed": seed}, str(path))
                run_spec(cfg)  # validate now
                runs.append((str(name), cfg))
            jobs.append(Job(str(scene), int(seed), tuple(runs), methods))
    return Suite(path.stem, tuple(jobs), float(raw.get("tolerance", 0.02)))


def shipped_difficulties() -> dict[str, dict]:
    """The difficulty levels of the shipped leaderboard (``easy``, ``medium``, ``hard``):
    run-config overrides, defined once in ``configs/leaderboard.yaml``."""
    from .config import shipped_config

    return dict(read_yaml(shipped_config("leaderboard.yaml"))["difficulties"])
