"""Suites: scenes × difficulties × methods × seeds, read from YAML (``configs/leaderboard.yaml``).

Keys: ``base`` (a run config for every run), ``scenes``, ``difficulties`` (name -> overrides),
``methods`` (names, or ``{name, method, params}``), ``seeds``, and optionally ``track``,
``tolerance`` (``check``), ``description``, ``requires`` (modules beyond the core; ``check`` skips
the suite without them) and ``backends`` (name -> overrides: each difficulty runs once per back end
as ``<difficulty>-<backend>``). docs/reference/suites.md describes every key.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import inspect
import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

from ..associators.registry import associator_class
from ..configs import shipped_config
from ..errors import UserError
from ..sources.base import short_name
from ..tracks.base import GuardedMetric, Track
from ..tracks.inference import infer_track
from ..tracks.registry import get_track, iter_tracks
from ..validation import brief, check_number
from .config import RunSpec, check_method, defaults, merge, run_spec
from .inputs import file_name
from .yamlfile import read_yaml

KEY_FORMAT = 1   # of a stored run's key: a new format never reuses runs stored under the old one
SUITE_KEYS = ("description", "track", "requires", "base", "scenes", "difficulties", "backends", "methods", "seeds",
              "tolerance", "ate_tolerance")


@dataclass(frozen=True)
class MethodEntry:
    """A leaderboard row label and the associator (name or ``pkg.module:Class``) behind it."""

    label: str
    method: str
    params: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Cell:
    """One scene, seed and difficulty of a suite: the run config each method runs on (``config``)."""

    scene: str
    seed: int
    difficulty: str
    cfg: dict

    @property
    def name(self) -> str:
        """The cell's scene or dataset by its short name (never a machine path)."""
        return short_name(self.scene)

    @property
    def scenario(self) -> str:
        return f"{self.name}/{self.difficulty}"

    def config(self, entry: MethodEntry) -> dict:
        """The run config of ``entry``'s method on this cell."""
        return {**self.cfg, "method": entry.method, "params": dict(entry.params)}


@dataclass(frozen=True, eq=False)
class Run:
    """The stored unit of a leaderboard: one method on one cell."""

    cell: Cell
    entry: MethodEntry

    @cached_property
    def spec(self) -> RunSpec:
        return run_spec(self.cell.config(self.entry))

    @cached_property
    def key(self) -> str:
        """What a stored run is looked up by: its checked settings (method and parameters included),
        its source's content key (``source.key``), the method class's file and the content of each
        file a parameter names; not its labels. The code it imported is checked when found
        (``inputs.RunInputs``). Computed once, so a file edited during a sweep cannot move a run
        between keys."""
        payload = {"format": KEY_FORMAT, "settings": settings_payload(self.spec.settings),
                   "source": self.spec.source.key, "class": _class_file(self.entry.method),
                   "param_files": _param_file_digests(self.entry.params)}
        return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:20]

    @property
    def label(self) -> dict:
        """The columns that say which run of the suite this is (not stored with it)."""
        return {"scenario": self.cell.scenario, "scene": self.cell.name, "difficulty": self.cell.difficulty,
                "method": self.entry.label, "seed": self.cell.seed}

    @property
    def name(self) -> str:
        return f"{self.entry.label} on {self.cell.scenario} seed {self.cell.seed}"


def settings_payload(settings) -> dict:
    """A run's typed settings as plain values (sections as mappings), for a key."""
    return {k: dataclasses.asdict(v) if dataclasses.is_dataclass(v) else v for k, v in settings.items()}


def _param_file_digests(params: dict) -> list[str]:
    """Each parameter-named file's content (``learned``'s ``params.model``), so one rewritten in
    place reruns."""
    paths = (Path(v) for v in params.values() if isinstance(v, str) and v)
    return [hashlib.sha256(p.read_bytes()).hexdigest()[:16] for p in paths if p.is_file()]


def _class_file(method: str) -> str:
    """The file defining a method's class, so a same-named module on another path is another run;
    the name alone where it does not resolve."""
    try:
        return file_name(Path(inspect.getsourcefile(associator_class(method))).resolve())
    except Exception:  # noqa: BLE001 - a broken plugin must not stop the sweep from being planned
        return method


@dataclass(frozen=True)
class Suite:
    name: str
    cells: tuple[Cell, ...]
    methods: tuple[MethodEntry, ...]
    tolerance: float
    ate_tolerance: float = 0.01   # m: a closed loop's ATE may rise this much above the baseline
    track: str = ""               # every run of a suite is on one track (one table, one baseline)
    loop: bool = False            # closed-loop runs: their trajectory is guarded too
    requires: tuple[str, ...] = ()   # modules beyond the core it needs (``requires: [gtsam]``)

    @property
    def track_impl(self) -> Track:
        return get_track(self.track)

    @cached_property
    def runs(self) -> tuple[Run, ...]:
        """Every stored unit of the suite: each cell (scene, seed, difficulty) × each method."""
        return tuple(Run(cell, entry) for cell in self.cells for entry in self.methods)

    def guards(self) -> tuple[GuardedMetric, ...]:
        """The columns ``check`` compares (the track's)."""
        return self.track_impl.guards(self.loop)

    def tolerances(self) -> dict[str, float]:
        return {"tolerance": self.tolerance, "ate_tolerance": self.ate_tolerance}

    def first_source(self):
        """The frame source of the suite's first run (its cache folder is checked before a sweep)."""
        return self.runs[0].spec.source if self.runs else None

    def scene_paths(self) -> dict[str, str]:
        """Each cell's scene by its short name (the scenario's) -> the scene it names (a user MJCF's path)."""
        return {cell.name: cell.scene for cell in self.cells}

    def rows(self) -> list[tuple[str, str]]:
        """The (scenario, method label) rows a run of this suite must produce."""
        return list(dict.fromkeys((run.cell.scenario, run.entry.label) for run in self.runs))


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
    cells = []
    for scene in scenes:
        for seed in seeds:
            for name, override in difficulties.items():
                cfg = base
                for part in override if isinstance(override, list) else [override]:
                    cfg = merge(cfg, part or {}, f"{path} difficulty {name}", track.name)
                cfg = merge(cfg, {"scene": scene, "seed": seed}, str(path), track.name)
                cells.append(Cell(str(scene), int(seed), str(name), cfg))
    ate_tolerance = check_number(raw.get("ate_tolerance", 0.01), f"ate_tolerance in {path}", lo=0)
    suite = Suite(path.stem, tuple(cells), methods, float(tolerance), float(ate_tolerance), track.name, loop,
                  _requires(raw, str(path)))
    for run in suite.runs:
        run.spec  # noqa: B018 - every run is resolved (checked) now, not in a worker
    return suite


def missing_modules(modules) -> str | None:
    """Why modules a suite ``requires`` cannot be used here (not installed), or None."""
    absent = [m for m in modules if importlib.util.find_spec(m) is None]
    return f"{', '.join(absent)} is not installed (pip install 'assocbench[{absent[0]}]')" if absent else None


def suite_requirements(path: Path) -> str | None:
    """Why the suite file at ``path`` cannot run here (its ``requires``), read before loading it
    (loading would refuse the same)."""
    return missing_modules(_requires(read_yaml(path), str(path)))


def _requires(raw: dict, where: str) -> tuple[str, ...]:
    """The suite's ``requires``: modules it needs beyond the core (``[gtsam]``)."""
    value = raw.get("requires") or []
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise UserError(f"'requires' in {where} must be a list of module names, e.g. [gtsam]")
    return tuple(value)


def suite_track(raw: dict, methods: tuple[MethodEntry, ...], where: str) -> Track:
    """The suite's one track: its ``track``, else what its methods and scenes imply; mixed tracks
    are refused."""
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
    """Each difficulty once per back end, ``<difficulty>-<backend>`` with both overrides; the
    difficulties alone when none is named."""
    if not backends:
        return difficulties
    out = {}
    for name, override in difficulties.items():
        for backend, extra in backends.items():
            out[f"{name}-{backend}"] = [override or {}, extra or {}]
    return out


def resolve_suite(name: str) -> Path:
    """A suite file: ``name`` if an existing path or ``.yaml``/``.yml``, else a registered track's
    shipped suite."""
    path = Path(name)
    if path.exists() or path.suffix in (".yaml", ".yml") or len(path.parts) > 1:
        return path
    shipped = {suite: entry.path for track in iter_tracks() for suite, entry in track.suites().items()}
    if name not in shipped:
        raise UserError(f"suite {name!r} is neither a file nor a shipped suite ({', '.join(shipped)}); "
                        "pass a YAML path")
    return shipped[name]


def shipped_difficulties() -> dict[str, dict]:
    """The shipped leaderboard's difficulty levels (``easy``, ``medium``, ``hard``), defined once in
    ``configs/leaderboard.yaml``."""
    return dict(read_yaml(shipped_config("leaderboard.yaml"))["difficulties"])
