"""Run configuration: one schema per track, its defaults, the user's YAML and ``--set`` overrides
merged on them, and the resolved ``RunSpec``.

Settings are the common ones (``RunKeys``, ``Limits``) and the track's (``Track.settings``), whose
dataclasses are the one source of defaults (``run``, a suite's ``base``, ``export``, the Gymnasium
envs). A key the track lacks is refused in one line naming the tracks that have it; every value is
checked once, when the typed ``Settings`` are built. The run's track is the one named, else the
method's, the scene's, or the default (``tracks.inference``).
"""

from __future__ import annotations

import copy
import difflib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..associators.registry import make_associator
from ..errors import UserError
from ..settings import Schema, Section, Settings
from ..sources.base import FrameSource
from ..tracks.base import Track
from ..tracks.capabilities import ClosedLoop, OwnFrames, Pictures, Requirements, has, lacks
from ..tracks.inference import infer_track, track_for_method
from ..tracks.registry import DEFAULT_TRACK, get_track, iter_tracks
from ..validation import brief, free_mapping, in_range
from .yamlfile import parse_sets, read_yaml

ORACLE = "oracle"   # the closed loop's reference method: the true association
LOOP_ONLY = "estimator"   # the section a run outside the closed loop must leave alone


@dataclass(frozen=True)
class RunKeys:
    """The settings every run has, whatever its track.

    track: the run's track (`assocbench list tracks`); null: the method's own track, else the
        scene's, else the default track.
    scene: what the track reads: a scene or dataset it ships (`assocbench list scenes`), or a file
        of its kind (an MJCF, a log); null: the track's first.
    frames: how many frames a run takes; null: the track's default (40 on a simulated track).
    seed: seeds the simulated noise, the belief's errors and the clutter.
    method: the associator (`assocbench list methods`) or pkg.module:Class.
    params: the method's parameters, e.g. {confidence: 0.95}.
    loop: true: the closed loop, the track's estimator updated with the method's own pairings.
    time_limit_s: the most one call of the method may take (s); a call past it is a failed frame.
    """

    track: str | None = field(default=None, metadata={"accepts": "null or a track's name (assocbench list tracks)"})
    scene: str | None = field(default=None, metadata={"accepts": "null, a scene or dataset the track ships, or a file"})
    frames: int | None = field(default=None, metadata=in_range(1, None, unit="frames"))
    seed: int = field(default=0, metadata=in_range(0, 2**32 - 1, unit="dimensionless"))
    method: str = field(default="jcbb", metadata={"accepts": "an associator's name (assocbench list methods) or "
                                                            "pkg.module:Class"})
    params: dict = field(default_factory=dict, metadata={"accepts": "a mapping (the method's parameters)"})
    loop: bool = False
    time_limit_s: float = field(default=30.0, metadata=in_range(0, 86400, lo_open=True, unit="s"))

    def check(self) -> None:
        free_mapping({"params": self.params}, "params")   # its numbers finite; the method checks the rest


@dataclass(frozen=True)
class Limits:
    """Sizes refused before anything runs (raise them here or with --set limits.frames=N).

    frames: the longest sequence a run may take (frames); rendering time grows with it.
    clutter: the most clutter features a frame (belief.clutter).
    """

    frames: int = field(default=5000, metadata=in_range(1, None, unit="frames"))
    clutter: int = field(default=1000, metadata=in_range(1, None, unit="features per frame"))


COMMON = Schema((RunKeys,), {"limits": Section(Limits)})


def run_schema(track: Track) -> Schema:
    """The whole schema of a run on ``track``: the common settings and the track's."""
    return COMMON + track.settings()


def defaults(track: Track | str | None = None) -> dict:
    """The run config's defaults on ``track`` (None: the default track), its name filled in."""
    track = get_track(track or DEFAULT_TRACK) if not isinstance(track, Track) else track
    return run_schema(track).defaults() | {"track": track.name}


def owners(key: str) -> list[str]:
    """The tracks whose schema has the dotted ``key`` (``belief.sigma_pixel``)."""
    section, _, leaf = key.partition(".")
    out = []
    for track in iter_tracks():
        schema = run_schema(track)
        if (not leaf and (section in schema.key_fields() or section in schema.sections)) or \
                (leaf and section in schema.sections and leaf in {f.name for f in schema.sections[section].fields()}):
            out.append(track.name)
    return out


def _paths(cfg: dict, sections: set[str]) -> list[str]:
    """Every dotted key of ``cfg`` (``limits.frames``, ``time_limit_s``); a section's keys dotted."""
    return [p for key, value in cfg.items()
            for p in ([key] + ([f"{key}.{k}" for k in value] if key in sections else []))]


def _unknown(key: str, known: list[str], where: str, track: str, everywhere: list[str]) -> UserError:
    """An unknown dotted ``key``: the tracks that have it, else that name elsewhere or the closest
    spelling."""
    others = [t for t in owners(key) if t != track]
    if others:
        return UserError(f"{key} is a setting of the {' and '.join(others)} track{'s' if len(others) > 1 else ''}, "
                         f"not of the {track} track this run is on ({where}): drop it, or name the run's track with "
                         "--track (track: in a config or suite)")
    leaf = key.rpartition(".")[2]
    moved = [p for p in everywhere if p.rpartition(".")[2] == leaf]
    close = difflib.get_close_matches(key, moved, n=1, cutoff=0) or difflib.get_close_matches(key, known, n=1)
    elsewhere = [(p, t.name) for t in iter_tracks() if t.name != track
                 for p in _paths(run_schema(t).defaults(), set(run_schema(t).sections)) if p.rpartition(".")[2] == leaf]
    hint = f" (did you mean {close[0]!r}?)" if close else \
        f" (did you mean {elsewhere[0][0]!r}? a setting of the {elsewhere[0][1]} track)" if elsewhere else ""
    return UserError(f"unknown key {key!r} in {where}{hint}; the {track} track's keys: {', '.join(known)}")


def merge(base: dict, override: dict, where: str, track: str | None = None) -> dict:
    """``base`` (a complete config of ``track``) updated by ``override``, whose keys must be
    ``base``'s; sections (not free-form ``params``) merge key by key."""
    track = track or str(base.get("track"))
    sections = set(run_schema(get_track(track)).sections)
    everywhere = _paths(base, sections)
    out = copy.deepcopy(base)
    for key, value in override.items():
        if key not in out:   # a section of another track is named by its first key (posts.min_points)
            dotted = f"{key}.{next(iter(value))}" if isinstance(value, dict) and value else str(key)
            raise _unknown(dotted, list(out), where, track, everywhere)
        if key not in sections:
            out[key] = value
            continue
        if not isinstance(value, dict):
            raise UserError(f"{key} in {where} must be a mapping, got {brief(value)}")
        for sub, item in value.items():
            if sub not in out[key]:
                raise _unknown(f"{key}.{sub}", [f"{key}.{k}" for k in out[key]], where, track, everywhere)
            out[key][sub] = item
    return out


def _named(layers: list[tuple[dict, str]], key: str) -> Any:
    """The value the last layer that gives ``key`` gives (None if none does)."""
    return next((layer[key] for layer, _ in reversed(layers) if layer.get(key) is not None), None)


def run_track(layers: list[tuple[dict, str]]) -> Track:
    """The track the layers name (the last ``track``), else the one inferred from their scene and method."""
    named = _named(layers, "track")
    if named is not None:
        return get_track(named)
    return infer_track(_named(layers, "scene"), _named(layers, "method"))


def load_run_config(config: str | Path | None = None, sets: list[str] | None = None, **flags) -> dict:
    """The run config: the track's defaults, the YAML ``config``, ``--set``, then the command-line
    ``flags``; a flag and ``--set`` disagreeing is refused (``_refuse_conflicts``)."""
    given = {k: v for k, v in flags.items() if v is not None}
    parsed = parse_sets(sets)
    _refuse_conflicts(given, parsed, sets or [])
    layers = ([(read_yaml(config), str(config))] if config else []) + [(parsed, "--set"), (given, "command-line flags")]
    track = run_track(layers)
    cfg = defaults(track)
    for layer, where in layers:
        cfg = merge(cfg, layer, where, track.name)
    cfg["track"] = track.name
    return cfg


def _refuse_conflicts(flags: dict, given: dict, sets: list[str]) -> None:
    """Refuse a key given by its flag and by ``--set`` with another value: one would be dropped
    silently."""
    for key in [k for k in flags if k in given and given[k] != flags[k]]:
        item = next(s for s in reversed(sets) if s.partition("=")[0].strip() == key)
        flag = f"--{key}" if flags[key] is True else f"--{key} {flags[key]}"
        raise UserError(f"{flag} and --set {item} disagree: give {key} once")


@dataclass(frozen=True)
class RunSpec:
    """A fully resolved run: its track, frame source and checked settings, and the method."""

    track: str                   # the registered track that reads the source
    source: FrameSource          # its frames (read lazily, in the worker)
    settings: Settings           # every setting, typed and checked (the common ones and the track's)
    method: str
    params: dict

    @property
    def track_impl(self) -> Track:
        """The registered ``Track`` of this run."""
        return get_track(self.track)

    @property
    def seed(self) -> int:
        return self.settings.seed

    @property
    def loop(self) -> bool:
        return self.settings.loop

    @property
    def time_limit_s(self) -> float:
        return float(self.settings.time_limit_s)

    @property
    def frames(self) -> int:
        return len(self.source)

    @property
    def belief(self) -> Any:
        """The open-loop belief's settings (a track with a ``belief`` section), else None."""
        return self.settings.get("belief")

    @property
    def estimator(self) -> Any:
        """The closed loop's estimator settings (a track with an ``estimator`` section), else None."""
        return self.settings.get(LOOP_ONLY)

    def setting(self, name: str) -> Any:
        """The settings section ``name`` (a track's own, e.g. ``icp``)."""
        return self.settings[name]

    def with_method(self, method: str, params: dict) -> RunSpec:
        """This run with another method (a suite's runs share everything else)."""
        return RunSpec(self.track, self.source, self.settings, method, dict(params))


def run_spec(cfg: dict) -> RunSpec:
    """Resolve a merged config into a ``RunSpec``, checking every value once before anything runs
    (types, ranges, the method built once, the closed loop, ``limits``)."""
    track = get_track(cfg.get("track") or infer_track(cfg.get("scene"), cfg.get("method")).name)
    cfg = merge(defaults(track), {k: v for k, v in cfg.items() if k != "track"}, "the run config", track.name)
    settings = run_schema(track).build(cfg)
    if not isinstance(settings.method, str) or not settings.method:
        raise UserError(f"method must be a name or pkg.module:Class, got {settings.method!r}")
    _check_track_can(track, settings, cfg)
    check_method(settings.method, settings.params, settings.loop, track)
    source = track.source(settings)
    _check_sizes(source, settings)
    return RunSpec(track.name, source, settings, settings.method, dict(settings.params))


def _check_track_can(track: Track, settings: Settings, cfg: dict) -> None:
    """Refuse what the track cannot do: run here (a missing package), a closed loop, estimator
    settings outside one."""
    why = track.unavailable() if has(track, Requirements) else None
    if why:
        raise UserError(f"the {track.name} track is unavailable here: {why}")
    if settings.loop and not has(track, ClosedLoop):
        raise lacks(track, "closed loop", "drop --loop (loop: true)")
    base = defaults(track).get(LOOP_ONLY)
    if not settings.loop and base is not None and cfg[LOOP_ONLY] != base:
        changed = next(k for k, v in cfg[LOOP_ONLY].items() if base.get(k) != v)
        raise UserError(f"{LOOP_ONLY}.{changed} applies to the closed loop only: add --loop (loop: true) or drop it")


def _check_sizes(source: FrameSource, settings: Settings) -> None:
    """Sizes that would render for hours or allocate GiB are refused before anything runs."""
    limits = settings.limits
    if len(source) > limits.frames:
        raise UserError(f"frames {len(source)} exceeds limits.frames = {limits.frames} (about 10 minutes of "
                        f"rendering); lower it or raise limits.frames (--set limits.frames=N, or in a suite's base)")
    belief = settings.get("belief")
    if belief is not None and belief.clutter > limits.clutter:
        raise UserError(f"belief.clutter {belief.clutter} exceeds limits.clutter = {limits.clutter} features per "
                        f"frame; lower it or raise limits.clutter (--set limits.clutter=N, or in a suite's base)")


def with_pictures(spec: RunSpec, what: str) -> RunSpec:
    """``spec``, or a one-line error when its track draws no pictures (``frame``, ``render``)."""
    track = spec.track_impl
    if not has(track, Pictures):
        elsewhere = getattr(track, "pictures_elsewhere", "") or \
            f"the leaderboard's pictures (`assocbench leaderboard --suite {next(iter(track.suites()), track.name)}`)"
        raise UserError(f"{what} does not serve the {track.name} track (scene {spec.source.name!r}): see its runs in "
                        f"{elsewhere}")
    return spec


def check_method(method: str, params: dict, loop: bool, track: Track) -> None:
    """Refuse an unknown method or bad parameters now (built once). ``oracle`` is closed-loop only;
    an ``OwnFrames`` track checks its methods; a class's ``check_track(track, params)`` is asked."""
    if has(track, OwnFrames):
        track.check_method(method, params)
        return
    own = track_for_method(method)
    if own is not None and own.name != track.name:
        raise UserError(f"method {method} runs on the {own.name} track (it is one of its own methods), not on the "
                        f"{track.name} track: drop --track, or name --track {own.name}")
    if method == ORACLE:
        if not loop:
            raise UserError("method 'oracle' (the true association) is the closed loop's reference; "
                            "use it with --loop (loop: true)")
        if params:
            raise UserError(f"method 'oracle' takes no parameters, got {sorted(params)}")
        return
    associator = make_associator(method, **params)
    hook = getattr(type(associator), "check_track", None)
    if callable(hook):
        hook(track.name, params)

