"""Run configuration: YAML files and ``--set key=value`` overrides, checked against a schema.

A run config is a nested mapping whose keys and defaults come from the dataclasses of each
stage (``DetectorConfig``, ``TruthConfig``, ``BeliefConfig``); unknown keys are errors.
"""

from __future__ import annotations

import copy
import re
import difflib
from dataclasses import asdict, dataclass
from importlib import resources
from pathlib import Path

import yaml

from ..associators.registry import make_associator
from ..belief.config import BeliefConfig
from ..errors import UserError
from ..estimators.config import EstimatorConfig
from ..tracks.dense.icp import IcpConfig
from ..tracks.dense.fusion import FusionConfig
from ..tracks.dense.depth_sensor import DepthConfig
from ..tracks.camera.detect import DetectorConfig
from ..sim.lidar import LidarConfig
from ..tracks.lines.extract import LineExtractorConfig
from ..tracks.lines.sequence import LineSequenceSpec
from ..sim.planar_scene import scene_track
from ..tracks.planar.sequence import PlanarSequenceSpec
from ..tracks.planar.post_detect import PostDetectorConfig
from ..sim.render import MAX_SIDE, MIN_SIDE, check_msaa
from ..tracks.camera.sequence import SequenceSpec
from ..sim.trajectory import check_trajectory_params
from ..tracks.camera.truth import TruthConfig
from ..validation import check_number
from .dense_spec import DenseConfig, DenseRunSpec, dense_run_spec, is_dense

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
    "lidar": asdict(LidarConfig()),
    "posts": asdict(PostDetectorConfig()),
    "lines": asdict(LineExtractorConfig()),
    "depth": asdict(DepthConfig()),
    "icp": asdict(IcpConfig()),
    "fusion": asdict(FusionConfig()),
    "dense": asdict(DenseConfig()),
    "belief": asdict(BeliefConfig()),
    "loop": False,
    "estimator": asdict(EstimatorConfig()),
    "method": "jcbb",
    "params": {},
    "time_limit_s": 30.0,
    "limits": {"frames": 5000, "clutter": 1000},
}
ORACLE = "oracle"   # the closed loop's reference method: the true association
FREE_FORM = {"trajectory_params", "params"}  # checked by the trajectory / associator itself


def shipped_config(name: str) -> Path:
    """Path of a YAML shipped in ``assocbench/configs`` (``default.yaml``, ``ci.yaml``...)."""
    return Path(str(resources.files("assocbench.configs"))) / name


class _UniqueKeyLoader(yaml.SafeLoader):
    """A safe YAML loader that refuses a key given twice in one mapping (YAML itself keeps the
    last silently, so a typo'd override would be lost without a word)."""

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
            value = yaml.load(raw, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader
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

    sequence: SequenceSpec | PlanarSequenceSpec | LineSequenceSpec   # the scene's track: camera, planar or lines
    belief: BeliefConfig
    seed: int
    method: str
    params: dict
    time_limit_s: float = 30.0   # per associate() call; a call past it is a failed frame
    loop: bool = False           # closed loop: the belief is the estimator's posterior
    estimator: EstimatorConfig = EstimatorConfig()


def _typed(cls, values: dict, section: str):
    if not isinstance(values, dict):
        raise UserError(f"{section} must be a mapping of settings, got {values!r}")
    try:
        return cls(**values)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, UserError):
            raise
        raise UserError(f"bad value in {section}: {exc}") from None


def _mapping(cfg: dict, key: str) -> dict:
    """A free-form section (``params``, ``trajectory_params``): a mapping whose numbers are finite."""
    value = cfg[key] if cfg[key] is not None else {}
    if not isinstance(value, dict):
        raise UserError(f"{key} must be a mapping such as {{name: value}}, got {value!r}")
    for name, item in value.items():
        if isinstance(item, float):
            check_number(item, f"{key}.{name}")
    return dict(value)


def _check_limits(cfg: dict) -> dict:
    """The size limits (``limits.frames``, ``limits.clutter``), themselves checked."""
    limits = cfg["limits"]
    return {k: check_number(limits[k], f"limits.{k}", integer=True, lo=1) for k in DEFAULTS["limits"]}


def _check_sizes(cfg: dict) -> None:
    """Sizes that would render for hours or allocate GiB are refused before anything runs."""
    limits = _check_limits(cfg)
    check_number(cfg["frames"], "frames", integer=True, lo=1)
    if cfg["frames"] > limits["frames"]:
        raise UserError(f"frames {cfg['frames']} exceeds limits.frames = {limits['frames']} (about 10 minutes of "
                        f"rendering); lower it or raise limits.frames (--set limits.frames=N, or in a suite's base)")
    clutter = cfg["belief"].get("clutter", 0) if isinstance(cfg["belief"], dict) else 0
    if isinstance(clutter, int) and not isinstance(clutter, bool) and clutter > limits["clutter"]:
        raise UserError(f"belief.clutter {clutter} exceeds limits.clutter = {limits['clutter']} features per "
                        f"frame; lower it or raise limits.clutter (--set limits.clutter=N, or in a suite's base)")
    res = cfg["resolution"]
    if not (isinstance(res, (list, tuple)) and len(res) == 2):
        raise UserError(f"resolution must be [width, height] in pixels, got {res!r}")
    for name, value in zip(("width", "height"), res):
        check_number(value, f"resolution {name}", integer=True, lo=MIN_SIDE, hi=MAX_SIDE)


def run_spec(cfg: dict) -> RunSpec | DenseRunSpec:
    """Resolve a merged config mapping into typed stage settings. Every value is checked here,
    before anything runs: types, finiteness, ranges, sizes against ``limits``, the method and
    its parameters (built once and thrown away). A dense method (projective, kdtree) gives the
    dense track's ``DenseRunSpec``."""
    _check_sizes(cfg)
    check_number(cfg["seed"], "seed", integer=True, lo=0, hi=2**32 - 1)
    check_number(cfg["time_limit_s"], "time_limit_s", lo=0, hi=86400, lo_open=True)
    check_msaa(cfg["msaa"])
    for key in ("scene", "method"):
        if not isinstance(cfg[key], str) or not cfg[key]:
            raise UserError(f"{key} must be a name or a path, got {cfg[key]!r}")
    if cfg["trajectory"] is not None and not isinstance(cfg["trajectory"], str):
        raise UserError(f"trajectory must be a name or null, got {cfg['trajectory']!r}")
    if not isinstance(cfg["loop"], bool):
        raise UserError(f"loop must be true or false, got {cfg['loop']!r}")
    if is_dense(cfg["method"]):
        return dense_run_spec(cfg, _typed, _mapping)
    estimator = _typed(EstimatorConfig, cfg["estimator"], "estimator")
    seq = TRACK_SPECS[scene_track(cfg["scene"])](cfg, estimator)
    params = _mapping(cfg, "params")
    check_method(cfg["method"], params, cfg["loop"])
    return RunSpec(seq, _typed(BeliefConfig, cfg["belief"], "belief"), cfg["seed"], cfg["method"],
                   params, float(cfg["time_limit_s"]), cfg["loop"], estimator)


def camera_sequence_spec(cfg: dict, estimator: EstimatorConfig) -> SequenceSpec:
    """The camera track's sequence: rendered frames, detected corners (``resolution``, ``msaa``,
    ``detector``, ``truth``); RGB-D depth at each feature for the closed loop's slam mode."""
    if estimator.name != "ekf":
        raise UserError(f"estimator.name {estimator.name} serves the planar track only; scene {cfg['scene']!r} is a "
                        "camera scene, whose estimator is ekf")
    res = cfg["resolution"]
    seq = SequenceSpec(
        scene=cfg["scene"], trajectory=cfg["trajectory"], frames=cfg["frames"], seed=cfg["seed"],
        width=res[0], height=res[1], msaa=cfg["msaa"], trajectory_params=_mapping(cfg, "trajectory_params"),
        detector=_typed(DetectorConfig, cfg["detector"], "detector"),
        truth=_typed(TruthConfig, cfg["truth"], "truth"),
        feature_depth=cfg["loop"] and estimator.mode == "slam",   # RGB-D, and the truth of texture corners
    )
    check_trajectory_params(seq.resolved_trajectory(), seq.trajectory_params)
    return seq


def planar_sequence_spec(cfg: dict, estimator: EstimatorConfig) -> PlanarSequenceSpec:
    """The planar track's sequence: lidar scans along the scene's path, posts detected in them
    (``lidar``, ``posts``); the camera settings (resolution, detector, truth) do not apply."""
    seq = PlanarSequenceSpec(scene=cfg["scene"], trajectory=cfg["trajectory"],
                             trajectory_params=_mapping(cfg, "trajectory_params"), frames=cfg["frames"],
                             seed=cfg["seed"], lidar=_typed(LidarConfig, cfg["lidar"], "lidar"),
                             posts=_typed(PostDetectorConfig, cfg["posts"], "posts"))
    seq.check()
    return seq


def line_sequence_spec(cfg: dict, estimator: EstimatorConfig) -> LineSequenceSpec:
    """The lines track's sequence: lidar scans along the scene's path, wall lines extracted from
    them (``lidar``, ``lines``); its estimator is the EKF localisation on the known map."""
    if estimator.name != "ekf" or estimator.mode != "localisation":
        raise UserError(f"scene {cfg['scene']!r} is a lines scene, whose estimator is the EKF localisation on the "
                        f"known map: set estimator.name: ekf and estimator.mode: localisation (got "
                        f"{estimator.name}, {estimator.mode})")
    seq = LineSequenceSpec(scene=cfg["scene"], trajectory=cfg["trajectory"],
                           trajectory_params=_mapping(cfg, "trajectory_params"), frames=cfg["frames"],
                           seed=cfg["seed"], lidar=_typed(LidarConfig, cfg["lidar"], "lidar"),
                           lines=_typed(LineExtractorConfig, cfg["lines"], "lines"))
    if seq.lidar.mode != "lidar":
        raise UserError(f"lidar.mode {seq.lidar.mode} serves the planar track's posts; lines are extracted from "
                        "ray-cast scans: set lidar.mode: lidar")
    seq.check()
    return seq


TRACK_SPECS = {"camera": camera_sequence_spec, "planar": planar_sequence_spec, "lines": line_sequence_spec}


def camera_only(spec: RunSpec, what: str) -> RunSpec:
    """``spec``, or a one-line error when its scene is a lidar one (planar or lines) and ``what``
    serves the camera track only (rendered pictures, the Gymnasium envs)."""
    if isinstance(spec, DenseRunSpec):
        raise UserError(f"{what} serves the camera track's features; method {spec.method} runs the dense track "
                        f"(depth frames): run it with `assocbench run`, and see its map in "
                        f"`assocbench leaderboard --suite dense`")
    if isinstance(spec.sequence, (PlanarSequenceSpec, LineSequenceSpec)):
        track = "planar" if isinstance(spec.sequence, PlanarSequenceSpec) else "lines"
        raise UserError(f"{what} serves the camera track; scene {spec.sequence.scene!r} is a {track} one (lidar "
                        f"scans): run it with `assocbench run`, and see it in the top views of "
                        f"`assocbench leaderboard --suite {track}`")
    return spec


def check_method(method: str, params: dict, loop: bool) -> None:
    """Refuse an unknown method or bad parameters now (built once and thrown away). ``oracle``
    (the true association) exists only in the closed loop, as its reference row."""
    if method == ORACLE:
        if not loop:
            raise UserError("method 'oracle' (the true association) is the closed loop's reference; "
                            "use it with --loop (loop: true)")
        if params:
            raise UserError(f"method 'oracle' takes no parameters, got {sorted(params)}")
        return
    make_associator(method, **params)
