"""Run configuration: YAML files and ``--set key=value`` overrides, checked against a schema.

A run config is a nested mapping whose keys and defaults come from the dataclasses of each
stage (``DetectorConfig``, ``TruthConfig``, ``BeliefConfig``); unknown keys are errors.
"""

from __future__ import annotations

import copy
import difflib
from dataclasses import asdict, dataclass
from importlib import resources
from pathlib import Path

import yaml

from ..belief.camera_belief import BeliefConfig
from ..errors import UserError
from ..sim.detect import DetectorConfig
from ..sim.render import check_msaa
from ..sim.sequence import SequenceSpec
from ..sim.truth import TruthConfig

DEFAULTS: dict = {
    "scene": "room",
    "trajectory": None,
    "trajectory_params": {},
    "frames": 40,
    "seed": 0,
    "resolution": [640, 480],
    "msaa": None,
    "detector": asdict(DetectorConfig()),
    "truth": asdict(TruthConfig()),
    "belief": asdict(BeliefConfig()),
    "method": "jcbb",
    "params": {},
    "time_limit_s": 30.0,
}
FREE_FORM = {"trajectory_params", "params"}  # checked by the trajectory / associator itself


def shipped_config(name: str) -> Path:
    """Path of a YAML shipped in ``assocbench/configs`` (``default.yaml``, ``ci.yaml``...)."""
    return Path(str(resources.files("assocbench.configs"))) / name


def read_yaml(path: str | Path) -> dict:
    """Parse a YAML mapping, or raise a one-line ``UserError``."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"config file {path} not found; pass an existing YAML file")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise UserError(f"malformed YAML in {path}{where}: {getattr(exc, 'problem', exc)}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise UserError(f"{path} must hold a mapping of keys to values, got {type(data).__name__}")
    return data


def _unknown(key: str, known, where: str) -> UserError:
    close = difflib.get_close_matches(key, list(known), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return UserError(f"unknown key {key!r} in {where}{hint}; known keys: {', '.join(known)}")


def merge(base: dict, override: dict, where: str, prefix: str = "") -> dict:
    """``base`` updated by ``override``; keys must exist in ``base`` except in free-form sections."""
    out = copy.deepcopy(base)
    for key, value in override.items():
        full = f"{prefix}{key}"
        if key not in out:
            raise _unknown(full, [f"{prefix}{k}" for k in out], where)
        if isinstance(out[key], dict) and key not in FREE_FORM:
            if not isinstance(value, dict):
                raise UserError(f"{full} in {where} must be a mapping, got {value!r}")
            out[key] = merge(out[key], value, where, f"{full}.")
        else:
            out[key] = value
    return out


def parse_sets(items: list[str] | None) -> dict:
    """``["belief.clutter=5", "frames=10"]`` -> nested mapping (values parsed as YAML)."""
    out: dict = {}
    for item in items or []:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set expects key=value, got {item!r}")
        try:
            value = yaml.safe_load(raw)
        except yaml.YAMLError:
            value = raw
        node = out
        parts = key.strip().split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return out


def load_run_config(config: str | Path | None = None, sets: list[str] | None = None, **flags) -> dict:
    """Defaults, then the YAML ``config`` (``configs/default.yaml`` if None), then ``--set``, then flags."""
    path = Path(config) if config else shipped_config("default.yaml")
    cfg = merge(DEFAULTS, read_yaml(path), str(path))
    cfg = merge(cfg, parse_sets(sets), "--set")
    return merge(cfg, {k: v for k, v in flags.items() if v is not None}, "command-line flags")


@dataclass(frozen=True)
class RunSpec:
    """A fully resolved run: which sequence, which belief, which method."""

    sequence: SequenceSpec
    belief: BeliefConfig
    seed: int
    method: str
    params: dict
    time_limit_s: float = 30.0   # per associate() call; a call past it is a failed frame


def _typed(cls, values: dict, section: str):
    try:
        return cls(**values)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, UserError):
            raise
        raise UserError(f"bad value in {section}: {exc}") from None


def run_spec(cfg: dict) -> RunSpec:
    """Resolve a merged config mapping into typed stage settings (values checked here)."""
    res = cfg["resolution"]
    if not (isinstance(res, (list, tuple)) and len(res) == 2 and all(isinstance(v, int) for v in res)):
        raise UserError(f"resolution must be [width, height] in pixels, got {res!r}")
    for key in ("frames", "seed"):
        if not isinstance(cfg[key], int) or cfg[key] < (1 if key == "frames" else 0):
            raise UserError(f"{key} must be a {'positive' if key == 'frames' else 'non-negative'} integer, "
                            f"got {cfg[key]!r}")
    check_msaa(cfg["msaa"])
    seq = SequenceSpec(
        scene=str(cfg["scene"]), trajectory=cfg["trajectory"], frames=cfg["frames"], seed=cfg["seed"],
        width=res[0], height=res[1], msaa=cfg["msaa"], trajectory_params=dict(cfg["trajectory_params"] or {}),
        detector=_typed(DetectorConfig, cfg["detector"], "detector"),
        truth=_typed(TruthConfig, cfg["truth"], "truth"),
    )
    seq.resolved_trajectory()
    return RunSpec(seq, _typed(BeliefConfig, cfg["belief"], "belief"), cfg["seed"], str(cfg["method"]),
                   dict(cfg["params"] or {}), float(cfg["time_limit_s"]))
