"""Generators of the shipped scenes, one module per track's scene convention (``camera``,
``planar``, ``lines``, ``dense``); ``python -m assocbench.sim.scenegen.<track> [FOLDER]`` rewrites
them (by default into the package's ``scenes/`` folder)."""

from pathlib import Path

SCENES_DIR = Path(__file__).resolve().parents[2] / "scenes"
