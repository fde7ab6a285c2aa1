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
    return (text or "").strip().splitlines()[0] if text and text.strip() else ""


def main(args: argparse.Namespace) -> int:
    from ..sim.planar_scenegen import PLANAR_SCENES
    from ..sim.scenegen import SCENES

    described = SCENES | PLANAR_SCENES

    sections = {
        "methods": available(),
        "scenes": {name: ("[planar] " if name in PLANAR_SCENES else "[camera] ")
                   + (_first_line(described[name].__doc__) if name in described else str(path))
                   for name, path in shipped_scenes().items()},
        "trajectories": {name: _first_line(fn.__doc__) for name, fn in TRAJECTORIES.items()},
    }
    for title, items in sections.items():
        if args.what and args.what != title:
            continue
        print(f"{title}:")
        width = max(len(k) for k in items)
        for name, line in items.items():
            print(f"  {name:<{width}}  {line}")
    return 0
