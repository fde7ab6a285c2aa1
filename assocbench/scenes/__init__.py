"""Shipped MuJoCo scenes (MJCF + textures), installed as ``assocbench.scenes``.

Rebuild them from a clone with ``python -m assocbench.sim.scenegen.camera`` (and ``.planar``,
``.lines``, ``.dense``); each writes into this folder unless given another.
"""
