"""The track of a run that names none: a method only one track runs (``OwnMethods``) implies it; a
scene name one track ships is that track's; an MJCF file belongs to the track whose convention it
follows (``SceneConvention``), built-ins asked first; no scene: the default track. A plugin raising
while asked is named in one line and skipped, and never takes a shipped scene from its track.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import UserError
from .base import Track
from .capabilities import OwnFrames, OwnMethods, SceneConvention, SceneMarks, has
from .registry import BUILTINS, DEFAULT_TRACK, get_track, iter_tracks


def scene_marks(path: Path) -> SceneMarks:
    """What an MJCF names (parsed, not compiled; a one-line error for bad XML)."""
    from ..sim.scene import mjcf_names

    return SceneMarks(path, *mjcf_names(path))


def _asked(track: Track, what: str, ask):
    """``ask()``; a plugin raising is one line naming it (a built-in raising is our bug: raised)."""
    try:
        return ask()
    except UserError:
        raise
    except Exception as exc:  # noqa: BLE001 - plugin code
        if track.name in BUILTINS:
            raise
        raise UserError(f"track plugin {track.name!r} ({type(track).__module__}) raised in {what}: "
                        f"{type(exc).__name__}: {exc}; pass --track to name the run's track") from None


def track_for_method(method: str) -> Track | None:
    """The one track that owns ``method`` (``OwnMethods``), or None when it serves any track."""
    for track in iter_tracks():
        if has(track, OwnMethods) and _asked(track, "claims_method", lambda t=track: t.claims_method(method)):
            return track
    return None


def shipped_track(scene: str) -> Track | None:
    """The track shipping a scene of this name, or None; an ``OwnFrames`` track is never inferred
    from a scene (its methods imply it)."""
    for track in iter_tracks():
        if not has(track, OwnFrames) and scene in _asked(track, "scenes", track.scenes):
            return track
    return None


def track_for_scene(scene: str | Path) -> Track:
    """The track of a scene: the one shipping it, else the one whose convention its MJCF follows
    (built-ins first); a file two tracks claim is refused."""
    shipped = shipped_track(str(scene))
    if shipped is not None:
        return shipped
    from ..sim.scene import resolve_scene_path

    marks = scene_marks(resolve_scene_path(scene))
    claims = [t for t in iter_tracks()
              if has(t, SceneConvention) and _asked(t, "claims_scene", lambda t=t: t.claims_scene(marks))]
    if len(claims) > 1:
        names = " and ".join(t.name for t in claims)
        raise UserError(f"MJCF {marks.path} follows the conventions of the {names} tracks: name the run's track "
                        f"with --track (track: in a config or suite)")
    if claims:
        return claims[0]
    fallback = [t for t in iter_tracks() if getattr(t, "fallback", False)]
    if fallback:
        return fallback[0]
    raise UserError(f"no track claims MJCF {marks.path}: name the run's track with --track")


def infer_track(scene: str | None, method: str | None) -> Track:
    """The run's track when it names none: the method's own, else the scene's, else the default."""
    own = track_for_method(method) if isinstance(method, str) and method else None
    if own is not None:
        return own
    if isinstance(scene, str | Path) and str(scene):
        return track_for_scene(scene)
    return get_track(DEFAULT_TRACK)
