"""Write the learned associator's training scenes (camera track) into examples/learned/scenes/.

Two convex halls of look-alike patches (``scenegen.camera.polygon_hall``) that no leaderboard
suite uses, so the shipped model is never trained on a scene it is scored on:

    python examples/learned/make_scenes.py
"""

from __future__ import annotations

from pathlib import Path

from assocbench.sim.scenegen.camera import SceneBuilder, polygon_hall, write_scene

HALLS = {
    "hexagon_hall": ((4.2, 0.0), (2.1, 3.1), (-1.9, 3.4), (-4.0, 0.4), (-2.3, -3.3), (1.8, -3.2)),
    "pentagon_hall": ((4.6, -0.5), (1.2, 4.0), (-3.8, 2.6), (-3.6, -2.9), (1.5, -3.9)),
}


def main(out: Path = Path(__file__).parent / "scenes") -> None:
    for name, vertices in HALLS.items():
        path, sb = write_scene(out, name, polygon_hall, builder=SceneBuilder(name), vertices=vertices, oriented=True)
        print(f"{path}: {sb.n_landmarks} landmarks")


if __name__ == "__main__":
    main()
