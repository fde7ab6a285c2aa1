"""Suites: scenes × difficulties × methods × seeds, read from YAML (``configs/leaderboard.yaml``).

A suite file has the keys ``base`` (a run config applied to every run), ``scenes``,
``difficulties`` (name -> run-config overrides, e.g. ``{belief: {sigma_rotation: 2}}``),
``methods`` (names, or mappings ``{name, method, params}`` so a label can point at a plugin),
``seeds``, and optionally ``tolerance`` (for ``check``), ``description`` and ``backends``
(name -> run-config overrides, e.g. ``{isam2: {estimator: {name: isam2}}}``): each difficulty
is then run once per back end, as the difficulty ``<difficulty>-<backend>``.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

from ..associators.registry import associator_class
from ..errors import UserError
from ..fingerprint import class_digest, package_digest
from ..sim.scene import scene_digest
from ..sim.waypoints import waypoint_digest
from ..tracks.base import GuardedMetric, Track, get_track, iter_tracks, track_for_run
from ..validation import brief, check_number
from .config import check_method, defaults, merge, read_yaml, run_spec

SUITE_KEYS = ("description", "base", "scenes", "difficulties", "backends", "methods", "seeds", "tolerance",
              "ate_tolerance")


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
        """Hash of the job's settings and of the code that runs it (this package and each method's
        package), so results stored by other code are never reused. Computed once per job: a
        source edited while a sweep runs must not make a job stored under one key be looked up
        under another."""
        code = [package_digest()] + [_method_digest(m.method) for m in self.methods] + self._track_digests()
        code.append(scene_digest(self.scene))   # the scene's content, not its path: an edited MJCF recomputes
        code += self._waypoint_digests()         # likewise a waypoint file's
        code += self._param_file_digests()       # and a file a method's parameter names (a learned model)
        payload = json.dumps([self.scene, self.seed, self.runs, [vars(m) for m in self.methods], code],
                             sort_keys=True, default=str)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]

    def _waypoint_digests(self) -> list[str]:
        """The content of each run's waypoint file (``trajectory: waypoints``, any track): its
        name alone is in the settings, and an edited file must drive the new path."""
        digests = (waypoint_digest(cfg.get("trajectory"), cfg.get("trajectory_params") or {}, self.scene)
                   for _, cfg in self.runs)
        return [d for d in digests if d is not None]

    def _param_file_digests(self) -> list[str]:
        """The content of each file a method's parameter names (``params.model`` of ``learned``, or
        a plugin's data file): the settings hold its path alone, and a file rewritten in place (a
        retrained model) must not reuse the numbers the old one made."""
        paths = (Path(v) for m in self.methods for v in m.params.values() if isinstance(v, str) and v)
        return [hashlib.sha256(p.read_bytes()).hexdigest()[:16] for p in paths if p.is_file()]

    def _track_digests(self) -> list[str]:
        """Digests of the job's tracks that live outside this package (a user's track module):
        editing one must not reuse numbers its old code made. Built-ins are in ``package_digest``."""
        found = {type(track_for_run(self.scene, m.method)) for m in self.methods}
        return sorted(class_digest(cls) for cls in found if not cls.__module__.startswith("assocbench."))


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
    track: str = "camera"         # every run of a suite is on one track (one table, one baseline)
    loop: bool = False            # closed-loop runs: their trajectory is guarded too

    @property
    def track_impl(self) -> Track:
        return get_track(self.track)

    def guards(self) -> tuple[GuardedMetric, ...]:
        """The columns ``check`` compares (the track's)."""
        return self.track_impl.check_metrics(self.loop)

    def tolerances(self) -> dict[str, float]:
        return {"tolerance": self.tolerance, "ate_tolerance": self.ate_tolerance}
    def rows(self) -> list[tuple[str, str]]:
        """The (scenario, method label) rows a run of this suite must produce."""
        first = {}
        for job in self.jobs:
            for difficulty, _ in job.runs:
                for m in job.methods:
                    first.setdefault((f"{job.scene}/{difficulty}", m.label), None)
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
    base = merge(defaults(), raw.get("base") or {}, f"{path} base")
    scenes = _list(raw, "scenes", [base["scene"]], str(path))
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
    methods = _methods(raw.get("methods"), str(path))
    parts = [p for o in difficulties.values() for p in (o if isinstance(o, list) else [o])]
    loop = base.get("loop") is True or any(isinstance(p, dict) and p.get("loop") is True for p in parts)
    track = suite_track(methods, scenes, base, str(path))
    for m in methods:   # unknown methods, broken plugins, bad parameters: now
        if track.has_problems:
            check_method(m.method, m.params, loop, track.name)
        else:
            track.check_method(m.method, m.params, loop)
    tolerance = check_number(raw.get("tolerance", 0.02), f"tolerance in {path}", lo=0)
    jobs = []
    for scene in scenes:
        for seed in seeds:
            runs = []
            for name, override in difficulties.items():
                cfg = base
                for part in override if isinstance(override, list) else [override]:
                    cfg = merge(cfg, part or {}, f"{path} difficulty {name}")
                # the run's method names its track (a dense method): the worker builds that track's run
                cfg = merge(cfg, {"scene": scene, "seed": seed, "method": methods[0].method}, str(path))
                run_spec(cfg)  # validate now
                runs.append((str(name), cfg))
            jobs.append(Job(str(scene), int(seed), tuple(runs), methods))
    ate_tolerance = check_number(raw.get("ate_tolerance", 0.01), f"ate_tolerance in {path}", lo=0)
    return Suite(path.stem, tuple(jobs), float(tolerance), float(ate_tolerance), track.name, loop)


def suite_track(methods: tuple[MethodEntry, ...], scenes: list, base: dict, where: str) -> Track:
    """The one track of a suite's runs: each method's own (a dense method), else each scene's;
    a suite mixing tracks is refused (its runs are scored differently: one table cannot hold them)."""
    found = {}
    for m in methods:
        for scene in scenes:
            found.setdefault(track_for_run(scene, m.method).name,
                             f"{m.label} on {scene}")
    if len(found) > 1:
        runs = "; ".join(f"{name}: {example}" for name, example in found.items())
        raise UserError(f"suite {where} mixes tracks ({runs}): a track's runs are scored differently, so put "
                        "them in separate suites")
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
    """A suite file: ``name`` itself when it is a path that exists or ends in .yaml/.yml, else
    the shipped ``configs/<name>.yaml`` of a registered track (``Track.suites``)."""
    from .config import shipped_config

    path = Path(name)
    if path.exists() or path.suffix in (".yaml", ".yml") or len(path.parts) > 1:
        return path
    shipped = shipped_config(f"{name}.yaml")
    if not shipped.is_file():
        known = ", ".join(s for track in iter_tracks() for s in track.suites)
        raise UserError(f"suite {name!r} is neither a file nor a shipped suite ({known}); pass a YAML path")
    return shipped


def shipped_difficulties() -> dict[str, dict]:
    """The difficulty levels of the shipped leaderboard (``easy``, ``medium``, ``hard``):
    run-config overrides, defined once in ``configs/leaderboard.yaml``."""
    from .config import shipped_config

    return dict(read_yaml(shipped_config("leaderboard.yaml"))["difficulties"])
