"""Suites: scenes × difficulties × methods × seeds, read from YAML (``configs/leaderboard.yaml``).

A suite file has the keys ``base`` (a run config applied to every run), ``scenes``,
``difficulties`` (name -> run-config overrides, e.g. ``{belief: {sigma_rotation: 2}}``),
``methods`` (names, or mappings ``{name, method, params}`` so a label can point at a plugin),
``seeds``, and optionally ``track`` (the suite's track; else inferred from its methods and
scenes), ``tolerance`` (for ``check``), ``description``, ``requires`` (modules beyond the core it
needs, ``[gtsam]``: ``check`` skips it where one is missing) and ``backends`` (name -> run-config
overrides, e.g. ``{isam2: {estimator: {name: isam2}}}``): each difficulty is then run once per back
end, as the difficulty ``<difficulty>-<backend>``. docs/reference/suites.md describes every key.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

from ..associators.registry import associator_class
from ..configs import shipped_config
from ..errors import UserError
from ..fingerprint import class_digest, package_digest
from ..sources.base import short_name
from ..tracks.base import GuardedMetric, Track
from ..tracks.inference import infer_track
from ..tracks.registry import get_track, iter_tracks
from ..validation import brief, check_number
from .config import check_method, defaults, merge, run_spec
from .yamlfile import read_yaml

SUITE_KEYS = ("description", "track", "requires", "base", "scenes", "difficulties", "backends", "methods", "seeds",
              "tolerance", "ate_tolerance")


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

    @cached_property
    def key(self) -> str:
        """Hash of the job's settings, its frame sources' content keys (``source.key``: the scene's or
        log's files, a waypoint file, the code that makes the frames) and the code that runs it (this
        package and each method's package), so results stored by other code or from other inputs
        are never reused. Computed once per job: a source edited while a sweep runs must not make a
        job stored under one key be looked up under another."""
        specs = [run_spec({**cfg, "scene": self.scene, "seed": self.seed}) for _, cfg in self.runs]
        code = [package_digest()] + [_method_digest(m.method) for m in self.methods] + self._track_digests(specs)
        code += [spec.source.key for spec in specs]
        code += self._param_file_digests()       # a file a method's parameter names (a learned model)
        payload = json.dumps([self.scene, self.seed, self.runs, [vars(m) for m in self.methods], code],
                             sort_keys=True, default=str)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]

    def _param_file_digests(self) -> list[str]:
        """The content of each file a method's parameter names (``params.model`` of ``learned``, or
        a plugin's data file): the settings hold its path alone, and a file rewritten in place (a
        retrained model) must not reuse the numbers the old one made."""
        paths = (Path(v) for m in self.methods for v in m.params.values() if isinstance(v, str) and v)
        return [hashlib.sha256(p.read_bytes()).hexdigest()[:16] for p in paths if p.is_file()]

    def _track_digests(self, specs: list) -> list[str]:
        """Digests of the job's track when it lives outside this package (a user's track module):
        editing it must not reuse numbers its old code made. Built-ins are in ``package_digest``."""
        if not specs:
            return []
        cls = type(specs[0].track_impl)
        return [] if cls.__module__.startswith("assocbench.") else [class_digest(cls)]

    @property
    def name(self) -> str:
        """The job's scene or dataset by its short name (never a machine path)."""
        return short_name(self.scene)


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
    ate_tolerance: float = 0.01   # m: a closed loop's ATE may rise this much above the baseline
    track: str = ""               # every run of a suite is on one track (one table, one baseline)
    loop: bool = False            # closed-loop runs: their trajectory is guarded too
    requires: tuple[str, ...] = ()   # modules beyond the core it needs (``requires: [gtsam]``)

    @property
    def track_impl(self) -> Track:
        return get_track(self.track)

    def guards(self) -> tuple[GuardedMetric, ...]:
        """The columns ``check`` compares (the track's)."""
        return self.track_impl.guards(self.loop)

    def tolerances(self) -> dict[str, float]:
        return {"tolerance": self.tolerance, "ate_tolerance": self.ate_tolerance}

    def first_source(self):
        """The frame source of the suite's first run (its cache folder is checked before a sweep)."""
        return run_spec(self.jobs[0].runs[0][1]).source if self.jobs else None

    def scene_paths(self) -> dict[str, str]:
        """Each job's scene by its short name (the scenario's) -> the scene it names (a user MJCF's path)."""
        return {job.name: job.scene for job in self.jobs}

    def rows(self) -> list[tuple[str, str]]:
        """The (scenario, method label) rows a run of this suite must produce."""
        first = {}
        for job in self.jobs:
            for difficulty, _ in job.runs:
                for m in job.methods:
                    first.setdefault((f"{job.name}/{difficulty}", m.label), None)
        return list(first)


def _methods(raw, where: str) -> tuple[MethodEntry, ...]:
    if not isinstance(raw, list) or not raw:
        raise UserError(f"'methods' in {where} must be a non-empty list")
    out = []
    for item in raw:
        if isinstance(item, str):
            out.append(MethodEntry(item, item))
        elif (isinstance(item, dict) and set(item) <= {"name", "method", "params"} and "method" in item
              and isinstance(item.get("params") or {}, dict)):
            out.append(MethodEntry(str(item.get("name", item["method"])), str(item["method"]), dict(item.get("params") or {})))
        else:
            raise UserError(f"bad method entry {brief(item)} in {where}: use a name or {{name, method, params}}")
    _refuse_duplicates([m.label for m in out], "method labels", where, "give each entry its own name")
    return tuple(out)


def _refuse_duplicates(items: list, what: str, where: str, fix: str) -> None:
    """Two rows of a suite with one label would be averaged into one row that claims twice the seeds."""
    seen = [x for k, x in enumerate(items) if x in items[:k]]
    if seen:
        raise UserError(f"duplicate {what} {', '.join(map(repr, dict.fromkeys(seen)))} in {where}: {fix}")


def _list(raw, key: str, default, where: str) -> list:
    value = raw.get(key) if raw.get(key) is not None else default
    if not isinstance(value, list) or not value:
        raise UserError(f"'{key}' in {where} must be a non-empty list, got {brief(value)}")
    return value


def load_suite(path: str | Path) -> Suite:
    """Read and check a suite file; every run config is resolved now, so errors come early."""
    path = Path(path)
    raw = read_yaml(path)
    for key in raw:
        if key not in SUITE_KEYS:
            raise UserError(f"unknown key {key!r} in {path}; known keys: {', '.join(SUITE_KEYS)}")
    if not isinstance(raw.get("base") or {}, dict):
        raise UserError(f"'base' in {path} must be a run-config mapping")
    methods = _methods(raw.get("methods"), str(path))
    track = suite_track(raw, methods, str(path))
    base = merge(defaults(track), {k: v for k, v in (raw.get("base") or {}).items() if k != "track"},
                 f"{path} base", track.name)
    scenes = _list(raw, "scenes", [base["scene"] or next(iter(track.scenes()), None)], str(path))
    difficulties = raw.get("difficulties") or {"default": {}}
    seeds = _list(raw, "seeds", [base["seed"]], str(path))
    for key in ("difficulties", "backends"):
        value = raw.get(key) or {}
        if not isinstance(value, dict) or not all(isinstance(v or {}, dict) for v in value.values()):
            raise UserError(f"'{key}' in {path} must map names to run-config overrides")
    difficulties = _crossed(difficulties, raw.get("backends") or {})
    for seed in seeds:
        check_number(seed, f"seeds entry in {path}", integer=True, lo=0, hi=2**32 - 1)
    if not all(isinstance(sc, str) for sc in scenes):
        raise UserError(f"'scenes' in {path} must be a list of scene names or MJCF paths")
    _refuse_duplicates(seeds, "seeds", str(path), "list each seed once")
    _refuse_duplicates(scenes, "scenes", str(path), "list each scene once")
    _refuse_duplicates([short_name(sc) for sc in scenes], "scene names", str(path),
                       "two files of one name would share their scenarios; rename one")
    parts = [p for o in difficulties.values() for p in (o if isinstance(o, list) else [o])]
    loop = base.get("loop") is True or any(isinstance(p, dict) and p.get("loop") is True for p in parts)
    for m in methods:   # unknown methods, broken plugins, bad parameters: now
        check_method(m.method, m.params, loop, track)
    tolerance = check_number(raw.get("tolerance", 0.02), f"tolerance in {path}", lo=0)
    jobs = []
    for scene in scenes:
        for seed in seeds:
            runs = []
            for name, override in difficulties.items():
                cfg = base
                for part in override if isinstance(override, list) else [override]:
                    cfg = merge(cfg, part or {}, f"{path} difficulty {name}", track.name)
                cfg = merge(cfg, {"scene": scene, "seed": seed, "method": methods[0].method}, str(path), track.name)
                run_spec(cfg)  # validate now
                runs.append((str(name), cfg))
            jobs.append(Job(str(scene), int(seed), tuple(runs), methods))
    ate_tolerance = check_number(raw.get("ate_tolerance", 0.01), f"ate_tolerance in {path}", lo=0)
    return Suite(path.stem, tuple(jobs), float(tolerance), float(ate_tolerance), track.name, loop,
                 _requires(raw, str(path)))


def missing_modules(modules) -> str | None:
    """Why modules a suite ``requires`` cannot be used here (not installed), or None."""
    absent = [m for m in modules if importlib.util.find_spec(m) is None]
    return f"{', '.join(absent)} is not installed (pip install 'assocbench[{absent[0]}]')" if absent else None


def suite_requirements(path: Path) -> str | None:
    """Why the suite file at ``path`` cannot run here (``missing_modules`` of its ``requires``),
    read before the suite is loaded: loading it resolves its runs, which would refuse the same."""
    return missing_modules(_requires(read_yaml(path), str(path)))


def _requires(raw: dict, where: str) -> tuple[str, ...]:
    """The suite's ``requires``: modules it needs beyond the core (``[gtsam]``)."""
    value = raw.get("requires") or []
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise UserError(f"'requires' in {where} must be a list of module names, e.g. [gtsam]")
    return tuple(value)


def suite_track(raw: dict, methods: tuple[MethodEntry, ...], where: str) -> Track:
    """The one track of a suite's runs: its ``track`` (or its base's), else the track each method
    and scene implies; a suite mixing tracks is refused (its runs are scored differently: one table
    cannot hold them)."""
    base = raw.get("base") or {}
    named = raw.get("track") or base.get("track")
    if named is not None:
        return get_track(named)
    scenes = raw.get("scenes") or [base.get("scene")]
    found = {}
    for m in methods:
        for scene in scenes if isinstance(scenes, list) else [None]:
            scene = scene if isinstance(scene, str) else None
            found.setdefault(infer_track(scene, m.method).name, f"{m.label} on {scene or 'the default scene'}")
    if len(found) > 1:
        runs = "; ".join(f"{name}: {example}" for name, example in found.items())
        raise UserError(f"suite {where} mixes tracks ({runs}): a track's runs are scored differently, so put "
                        "them in separate suites (or name the suite's track: track: NAME)")
    return get_track(next(iter(found)))


def _crossed(difficulties: dict, backends: dict) -> dict:
    """Each difficulty once per back end, as ``<difficulty>-<backend>`` with both overrides (the
    back end's last); the difficulties themselves when no back end is named."""
    if not backends:
        return difficulties
    out = {}
    for name, override in difficulties.items():
        for backend, extra in backends.items():
            out[f"{name}-{backend}"] = [override or {}, extra or {}]
    return out


def resolve_suite(name: str) -> Path:
    """A suite file: ``name`` itself when it is a path that exists or ends in .yaml/.yml, else a
    registered track's shipped suite of that name (``Track.suites``: the built-ins' in
    ``assocbench/configs``, a plugin's in its own package)."""
    path = Path(name)
    if path.exists() or path.suffix in (".yaml", ".yml") or len(path.parts) > 1:
        return path
    shipped = {suite: entry.path for track in iter_tracks() for suite, entry in track.suites().items()}
    if name not in shipped:
        raise UserError(f"suite {name!r} is neither a file nor a shipped suite ({', '.join(shipped)}); "
                        "pass a YAML path")
    return shipped[name]


def shipped_difficulties() -> dict[str, dict]:
    """The difficulty levels of the shipped leaderboard (``easy``, ``medium``, ``hard``):
    run-config overrides, defined once in ``configs/leaderboard.yaml``."""
    return dict(read_yaml(shipped_config("leaderboard.yaml"))["difficulties"])
