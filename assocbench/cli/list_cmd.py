"""``assocbench list``: methods (plugins included), scenes and trajectories."""

from __future__ import annotations

import argparse

from ..associators.registry import available
from ..sim.scene import shipped_scenes
from ..sim.trajectory import TRAJECTORIES

NAME = "list"
HELP = "list methods, scenes and trajectories"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("what", nargs="?", choices=("methods", "scenes", "trajectories"), help="only this kind")


def _first_line(text: str | None) -> str:
    """The docstring's first paragraph on one line."""
    return " ".join((text or "").strip().split("\n\n")[0].split())


def dense_methods() -> dict[str, str]:
    """The dense track's associators (the method implies the track)."""
    from ..associators.dense.registry import DENSE_METHODS

    return {name: "[dense] " + _first_line(cls.__doc__) for name, cls in DENSE_METHODS.items()}


def main(args: argparse.Namespace) -> int:
    from ..sim.scenegen.dense import DENSE_SCENES
    from ..sim.scenegen.lines import LINE_SCENES
    from ..sim.scenegen.planar import PLANAR_SCENES
    from ..sim.scenegen.camera import SCENES

    described = SCENES | PLANAR_SCENES | LINE_SCENES | DENSE_SCENES
    track = {name: "planar" for name in PLANAR_SCENES} | {name: "lines" for name in LINE_SCENES}

    sections = {
        "methods": available() | dense_methods(),
        "scenes": {name: f"[{track.get(name, 'camera')}] "
                   + (_first_line(described[name].__doc__) if name in described else str(path))
                   for name, path in shipped_scenes().items()},
        "trajectories": [(name, "[camera] " + _first_line(fn.__doc__)) for name, fn in TRAJECTORIES.items()]
        + [("loop", "[planar, lines] a shipped planar or lines scene's own path (laps, start), its default"),
           ("ellipse", "[planar, lines] an ellipse around the posts (lines: the wall faces) clear of every obstacle "
                       "(laps, start, scale), a user MJCF's default")],
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
