"""``assocbench list``: methods (plugins included), scenes, trajectories and tracks, each tagged with its track."""

from __future__ import annotations

import argparse

from ..associators.registry import available
from ..sim.scene import shipped_scenes
from ..tracks.base import iter_tracks, track_for_method, track_for_scene

NAME = "list"
HELP = "list methods, scenes, trajectories and tracks"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("what", nargs="?", choices=("methods", "scenes", "trajectories", "tracks"), help="only this kind")


def main(args: argparse.Namespace) -> int:
    tracks = list(iter_tracks())
    listed = {name: f"[{t.name}] {line}" for t in tracks for name, line in t.shipped_scenes().items()}
    sections = {
        "methods": {name: (f"[{own.name}] " if (own := track_for_method(name)) else "") + line
                    for name, line in available().items()},
        "scenes": {name: listed.get(name, f"[{track_for_scene(path).name}] {path}")
                   for name, path in shipped_scenes().items()},
        "trajectories": _trajectories(tracks),
        "tracks": {t.name: t.summary for t in tracks},
    }
    for title, items in sections.items():
        if args.what and args.what != title:
            continue
        print(f"{title}:")
        rows = list(items.items()) if isinstance(items, dict) else items
        width = max(len(k) for k, _ in rows)
        for name, line in rows:
            print(f"  {name:<{width}}  {line}")
    return 0


def _trajectories(tracks: list) -> dict[str, str]:
    """Each trajectory once, tagged with every track that has it; where tracks describe it
    differently (``loop``, ``waypoints``: a camera's path and a robot's), each description after
    the tracks it belongs to."""
    described: dict[str, dict[str, list[str]]] = {}
    for t in tracks:
        for name, line in t.trajectories():
            described.setdefault(name, {}).setdefault(line, []).append(t.name)
    return {name: "; ".join(f"[{', '.join(owners)}] {line.rstrip('.')}" for line, owners in lines.items())
            for name, lines in described.items()}
