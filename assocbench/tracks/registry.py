"""The registry of tracks, each loaded only when asked for:

* built-ins by lazy ``module:Class`` strings (as Gymnasium's ``EnvSpec``): asking for one imports
  its module alone;
* installed packages' entry points in the group ``assocbench.tracks`` (named as the track);
* modules named in ``ASSOCBENCH_TRACKS`` (``pkg.mod[,pkg.mod2]``) that call ``register_track`` when
  imported, read on every ask so it reaches the workers.

A plugin that fails to load is named in one line and never stops a run of another track.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from importlib import import_module, metadata

from ..errors import UserError
from .base import Track, missing_hooks

ENTRY_POINT_GROUP = "assocbench.tracks"
MODULES_VARIABLE = "ASSOCBENCH_TRACKS"   # modules that register a track when imported
BUILTINS = {"camera": "assocbench.tracks.camera.track:CameraTrack",
            "planar": "assocbench.tracks.planar.track:PlanarTrack",
            "lines": "assocbench.tracks.lines.track:LinesTrack",
            "dense": "assocbench.tracks.dense.track:DenseTrack",
            "photos": "assocbench.tracks.photos.track:PhotosTrack",
            "planar_log": "assocbench.tracks.planar_log.track:PlanarLogTrack"}
DEFAULT_TRACK = "camera"   # a run that names no track, no scene and no method of a track's own

_TRACKS: dict[str, Track] = {}
_BROKEN: dict[str, str] = {}   # entry-point plugins that failed to load: name -> why


def register_track(track: Track | type[Track]) -> Track:
    """Add ``track`` (a ``Track`` subclass or instance) to the registry; a one-line ``UserError``
    for a name taken by another track or a track that misses a core hook."""
    inst = track() if isinstance(track, type) else track
    if not isinstance(inst, Track) or not inst.name:
        raise UserError(f"{track!r} is not a Track with a name: subclass assocbench.tracks.base.Track")
    missing = missing_hooks(inst)
    if missing:
        raise UserError(f"track {inst.name!r} ({type(inst).__module__}) lacks the core hooks {', '.join(missing)}; "
                        "see docs/howto/add-track.md")
    other = _TRACKS.get(inst.name)
    if other is not None and type(other) is not type(inst):
        raise UserError(f"track name {inst.name!r} is taken by {type(other).__module__}; choose another name")
    _TRACKS[inst.name] = inst
    return inst


def _load_builtin(name: str) -> None:
    module, _, cls = BUILTINS[name].partition(":")
    register_track(getattr(import_module(module), cls))


def _plugins() -> list[metadata.EntryPoint]:
    return list(metadata.entry_points(group=ENTRY_POINT_GROUP))


def _load_plugin(ep: metadata.EntryPoint) -> None:
    """Load one entry-point plugin; a broken one is remembered with its reason (named when asked
    for), not raised."""
    if ep.name in _BROKEN:
        return
    try:
        register_track(ep.load())
    except Exception as exc:  # noqa: BLE001 - plugin code
        _BROKEN[ep.name] = f"track plugin {ep.name!r} ({ep.value}) failed to load: {type(exc).__name__}: {exc}"


def _load_named_modules() -> None:
    """Import each module named in ``ASSOCBENCH_TRACKS``, read on every call (a worker may get it
    later)."""
    for name in filter(None, (n.strip() for n in os.environ.get(MODULES_VARIABLE, "").split(","))):
        if name in sys.modules:
            continue
        try:
            import_module(name)
        except UserError:
            raise
        except Exception as exc:  # noqa: BLE001 - a broken module is named in one line
            raise UserError(f"track module {name!r} named in {MODULES_VARIABLE} failed to import: "
                            f"{type(exc).__name__}: {exc} (is its folder on PYTHONPATH?)") from None


def get_track(name: str) -> Track:
    """The registered track called ``name``, loading only what it takes to find it."""
    if not isinstance(name, str) or not name:
        raise UserError(f"track must be a track's name, got {name!r}")
    if name not in _TRACKS:
        if name in BUILTINS:
            _load_builtin(name)
        else:
            _load_named_modules()
            for ep in _plugins():
                if ep.name == name:
                    _load_plugin(ep)
            if name not in _TRACKS and name in _BROKEN:
                raise UserError(_BROKEN[name])
            if name not in _TRACKS:   # a plugin whose entry point has another name than its track
                for ep in _plugins():
                    _load_plugin(ep)
    if name not in _TRACKS:
        raise UserError(f"unknown track {name!r}: choose one of {', '.join(track_names())} (assocbench list tracks)")
    return _TRACKS[name]


def tracks() -> dict[str, Track]:
    """Every registered track by name, all loaded: built-ins first, then plugins and named modules
    as registered; a plugin failing to load is left out with one line on stderr."""
    for name in BUILTINS:
        if name not in _TRACKS:
            _load_builtin(name)
    for ep in _plugins():
        _load_plugin(ep)
    for why in _BROKEN.values():
        _warn_once(why)
    _load_named_modules()
    ordered = {name: _TRACKS[name] for name in BUILTINS}
    return ordered | {name: track for name, track in _TRACKS.items() if name not in ordered}


_warned: set[str] = set()


def _warn_once(line: str) -> None:
    if line not in _warned:
        _warned.add(line)
        print(f"assocbench: {line}; it is left out", file=sys.stderr)


def track_names() -> list[str]:
    """The names of every track that can be asked for, without loading any."""
    names = list(BUILTINS) + [ep.name for ep in _plugins()] + list(_TRACKS)
    return list(dict.fromkeys(names))


def iter_tracks() -> Iterator[Track]:
    """The registered tracks (``tracks``), all loaded."""
    return iter(tracks().values())
