"""Shipped MuJoCo scenes (MJCF + textures), installed as ``assocbench.envs``.

Rebuild with ``python -m assocbench.sim.scenegen envs``.
"""
