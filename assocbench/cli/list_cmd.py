"""``assocbench list``: tracks, methods (plugins included), scenes, suites and trajectories, each
tagged with its track."""

from __future__ import annotations

import argparse

from ..associators.registry import available
from ..tracks.capabilities import Requirements, Trajectories, has
from ..tracks.inference import track_for_method
from ..tracks.registry import iter_tracks

NAME = "list"
HELP = "list tracks, methods, scenes, suites and trajectories"
KINDS = ("tracks", "methods", "scenes", "suites", "trajectories")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("what", nargs="?", choices=KINDS, help="only this kind")


def main(args: argparse.Namespace) -> int:
    tracks = list(iter_tracks())
    sections = {
        "tracks": {t.name: t.summary + _unavailable(t) for t in tracks},
        "methods": {name: (f"[{own.name}] " if (own := track_for_method(name)) else "") + line
                    for name, line in available().items()},
        "scenes": {name: f"[{t.name}] {line}" for t in tracks for name, line in t.scenes().items()},
        "suites": {name: f"[{t.name}] {entry.path.name}" + (" (check)" if entry.ci else "")
                   for t in tracks for name, entry in t.suites().items()},
        "trajectories": _trajectories(tracks),
    }
    for title in KINDS:
        if args.what and args.what != title:
            continue
        print(f"{title}:")
        items = sections[title]
        width = max((len(k) for k in items), default=0)
        for name, line in items.items():
            print(f"  {name:<{width}}  {line}")
    return 0


def _unavailable(track) -> str:
    why = track.unavailable() if has(track, Requirements) else None
    return f" (unavailable here: {why})" if why else ""


def _trajectories(tracks: list) -> dict[str, str]:
    """Each trajectory once, tagged with every track that has it; where tracks describe it
    differently (``loop``, ``waypoints``: a flying sensor's path and a robot's), each description after
    the tracks it belongs to."""
    described: dict[str, dict[str, list[str]]] = {}
    for t in tracks:
        for name, line in (t.trajectories() if has(t, Trajectories) else []):
            described.setdefault(name, {}).setdefault(line, []).append(t.name)
    return {name: "; ".join(f"[{', '.join(owners)}] {line.rstrip('.')}" for line, owners in lines.items())
            for name, lines in described.items()}
