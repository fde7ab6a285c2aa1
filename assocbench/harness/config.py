"""Run configuration: YAML files and ``--set key=value`` overrides, checked against a schema.

A run config is a nested mapping whose keys and defaults come from the dataclasses of each
stage (``DetectorConfig``, ``TruthConfig``, ``BeliefConfig``); unknown keys are errors.
"""

from __future__ import annotations

import copy
import difflib
import re
from dataclasses import asdict, dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from ..associators.registry import make_associator
from ..belief.config import BeliefConfig
from ..errors import UserError
from ..estimators.config import EstimatorConfig
from ..sim.render import MAX_SIDE, MIN_SIDE, check_msaa
from ..tracks.base import Track, get_track, iter_tracks, track_for_run
from ..validation import BoundedLoader, brief, check_number, free_mapping, typed_section

COMMON: dict = {
    "scene": "room",
    "trajectory": None,
    "trajectory_params": {},
    "frames": 40,
    "seed": 0,
    "resolution": [640, 480],
    "msaa": None,
    "belief": asdict(BeliefConfig()),
    "loop": False,
    "estimator": asdict(EstimatorConfig()),
    "method": "jcbb",
    "params": {},
    "time_limit_s": 30.0,
    "limits": {"frames": 5000, "clutter": 1000},
}


def defaults() -> dict:
    """The run config's schema and defaults: the settings every run has, then each registered
    track's sections (a section two tracks share, such as ``lidar``, must agree)."""
    out = copy.deepcopy(COMMON)
    for track in iter_tracks():
        for name, section in track.config_sections().items():
            if name in out and out[name] != section:
                raise UserError(f"track {track.name} declares settings section {name!r} with other defaults than "
                                "another track or the common settings; rename its section")
            out[name] = copy.deepcopy(section)
    return out


ORACLE = "oracle"   # the closed loop's reference method: the true association
FREE_FORM = {"trajectory_params", "params"}  # checked by the trajectory / associator itself


def shipped_config(name: str) -> Path:
    """Path of a YAML shipped in ``assocbench/configs`` (``default.yaml``, ``ci.yaml``...)."""
    return Path(str(resources.files("assocbench.configs"))) / name


class _UniqueKeyLoader(BoundedLoader):
    """A safe YAML loader that refuses a key given twice in one mapping (YAML itself keeps the
    last silently, so a typo'd override would be lost without a word), and an alias bomb
    (``BoundedLoader``)."""

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


def _paths(cfg: dict, prefix: str = "") -> list[str]:
    """Every dotted key of ``cfg`` (``limits.frames``, ``time_limit_s``), free-form sections as one key."""
    out = []
    for key, value in cfg.items():
        out.append(f"{prefix}{key}")
        if isinstance(value, dict) and key not in FREE_FORM:
            out += _paths(value, f"{prefix}{key}.")
    return out


def _unknown(key: str, known: list[str], where: str, everywhere: list[str]) -> UserError:
    """An unknown dotted ``key``; the hint names the key of that name elsewhere in the config
    (``limits.time_limit_s`` -> ``time_limit_s``), else the closest spelling at its own level."""
    leaf = key.rpartition(".")[2]
    moved = [p for p in everywhere if p.rpartition(".")[2] == leaf]
    close = difflib.get_close_matches(key, moved, n=1, cutoff=0) or difflib.get_close_matches(key, known, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return UserError(f"unknown key {key!r} in {where}{hint}; known keys: {', '.join(known)}")


def merge(base: dict, override: dict, where: str, prefix: str = "", everywhere: list[str] | None = None) -> dict:
    """``base`` updated by ``override``; keys must exist in ``base`` except in free-form sections.
    ``everywhere``: every dotted key of the whole config, for the hint of an unknown one (the
    top-level call takes ``base``'s)."""
    everywhere = _paths(base) if everywhere is None else everywhere
    out = copy.deepcopy(base)
    for key, value in override.items():
        full = f"{prefix}{key}"
        if key not in out:
            raise _unknown(full, [f"{prefix}{k}" for k in out], where, everywhere)
        if isinstance(out[key], dict) and key not in FREE_FORM:
            if not isinstance(value, dict):
                raise UserError(f"{full} in {where} must be a mapping, got {brief(value)}")
            out[key] = merge(out[key], value, where, f"{full}.", everywhere)
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
    cfg = merge(defaults(), read_yaml(path), str(path))
    given = parse_sets(sets)
    flags = {k: v for k, v in flags.items() if v is not None}
    _refuse_conflicts(flags, given, sets or [])
    cfg = merge(cfg, given, "--set")
    return merge(cfg, flags, "command-line flags")


def _refuse_conflicts(flags: dict, given: dict, sets: list[str]) -> None:
    """Refuse a key given both by its flag and by ``--set`` with another value: the flag would win
    and the other value, right or wrong, would be dropped without a word."""
    for key in [k for k in flags if k in given and given[k] != flags[k]]:
        item = next(s for s in reversed(sets) if s.partition("=")[0].strip() == key)
        flag = f"--{key}" if flags[key] is True else f"--{key} {flags[key]}"
        raise UserError(f"{flag} and --set {item} disagree: give {key} once")


@dataclass(frozen=True)
class RunSpec:
    """A fully resolved run: which sequence, which belief, which method."""

    sequence: Any                # the track's sequence spec
    belief: BeliefConfig
    seed: int
    method: str
    params: dict
    time_limit_s: float = 30.0   # per associate() call; a call past it is a failed frame
    loop: bool = False           # closed loop: the belief is the estimator's posterior
    estimator: EstimatorConfig = EstimatorConfig()
    track: str = "camera"        # the registered track that makes the sequence and its problems
    settings: tuple = ()          # the track's own typed sections, ((name, value), ...) (Track.run_settings)

    @property
    def track_impl(self) -> Track:
        """The registered ``Track`` of this run."""
        return get_track(self.track)

    def setting(self, name: str):
        """The track's typed settings section ``name`` (e.g. the dense track's ``icp``)."""
        return dict(self.settings)[name]


def _check_limits(cfg: dict) -> dict:
    """The size limits (``limits.frames``, ``limits.clutter``), themselves checked."""
    limits = cfg["limits"]
    return {k: check_number(limits[k], f"limits.{k}", integer=True, lo=1) for k in COMMON["limits"]}


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


def run_spec(cfg: dict) -> RunSpec:
    """Resolve a merged config mapping into typed stage settings. Every value is checked here,
    before anything runs: types, finiteness, ranges, sizes against ``limits``, the method and
    its parameters (built once and thrown away). The run's track is the method's own (a dense
    method) or the scene's; the track reads its sections (``Track.sequence_spec``,
    ``Track.run_settings``)."""
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
    track = track_for_run(cfg["scene"], cfg["method"])
    check_every_section(cfg, track)
    estimator = typed_section(EstimatorConfig, cfg["estimator"], "estimator")
    seq = track.sequence_spec(cfg, estimator)
    settings = track.run_settings(cfg)
    params = free_mapping(cfg, "params")
    if track.has_problems:
        check_method(cfg["method"], params, cfg["loop"], track.name)
    else:
        track.check_method(cfg["method"], params, cfg["loop"])
    return RunSpec(seq, typed_section(BeliefConfig, cfg["belief"], "belief"), cfg["seed"], cfg["method"],
                   params, float(cfg["time_limit_s"]), cfg["loop"], estimator, track.name, settings)


def check_every_section(cfg: dict, track: Track) -> None:
    """Check every track's settings, used by this run or not (a NaN in a section the run ignores
    is still a mistake), and refuse a setting that cannot apply to the run: another track's
    section changed from its defaults, or the estimator's settings outside the closed loop."""
    base = defaults()
    for other in iter_tracks():
        for name, cls in other.section_types().items():
            section = typed_section(cls, cfg[name], name)
            if callable(getattr(section, "check", None)):
                section.check()
    used = set(COMMON) | set(track.config_sections())
    for name in base:
        if name not in used and cfg[name] != base[name]:
            owners = [t.name for t in iter_tracks() if name in t.config_sections()]
            changed = next(f"{name}.{k}" for k, v in cfg[name].items() if base[name].get(k) != v)
            raise UserError(f"{changed} is a setting of the {' and '.join(owners)} track, but this run is on the "
                            f"{track.name} track (scene {cfg['scene']!r}, method {cfg['method']!r}): drop it")
    if not cfg["loop"] and cfg["estimator"] != base["estimator"]:
        changed = next(k for k, v in cfg["estimator"].items() if base["estimator"].get(k) != v)
        raise UserError(f"estimator.{changed} applies to the closed loop only: add --loop (loop: true) or drop it")


def with_pictures(spec: RunSpec, what: str) -> RunSpec:
    """``spec``, or a one-line error saying where to look instead when its track has no pictures
    for ``what`` (``frame``, ``render``: ``Track.pictures``)."""
    track = get_track(spec.track)
    if not track.pictures:
        instead = track.pictures_elsewhere or f"`assocbench leaderboard --suite {next(iter(track.suites), track.name)}`"
        raise UserError(f"{what} does not serve the {track.name} track (scene {spec.sequence.scene!r}): "
                        f"see its runs in {instead}")
    return spec


def check_method(method: str, params: dict, loop: bool, track: str | None = None) -> None:
    """Refuse an unknown method or bad parameters now (built once and thrown away). ``oracle``
    (the true association) exists only in the closed loop, as its reference row. A method whose
    class has ``check_track(track, params)`` (a learned model of one track) is asked about ``track``."""
    if method == ORACLE:
        if not loop:
            raise UserError("method 'oracle' (the true association) is the closed loop's reference; "
                            "use it with --loop (loop: true)")
        if params:
            raise UserError(f"method 'oracle' takes no parameters, got {sorted(params)}")
        return
    associator = make_associator(method, **params)
    hook = getattr(type(associator), "check_track", None)
    if track is not None and callable(hook):
        hook(track, params)
