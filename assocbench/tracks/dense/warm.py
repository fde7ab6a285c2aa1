"""Load or compile the dense kernels once per process, on tiny inputs (``kernels.warm``)."""

from __future__ import annotations

import numpy as np

from ...kernels import warm
from ...models.camera import Intrinsics
from ...models.depth_frame import DepthFrame, normal_map, vertex_map


def tiny_frame() -> DepthFrame:
    """A 6 x 6 frame of a plane 1 m in front of the camera (identity pose): 16 pixels with a normal."""
    K = Intrinsics.from_fovy(6, 6, 60.0)
    depth = np.ones((6, 6))
    V = vertex_map(depth, K)
    return DepthFrame(K, depth, V, normal_map(V), V.copy(), np.zeros((6, 6), np.int64), np.eye(3), np.zeros(3))


def warm_dense() -> float | None:
    """Run the projective association and one ICP iteration on a tiny frame so that their
    kernels are loaded (or compiled, with one line on stderr) before anything is timed.
    Returns the seconds spent compiling, None when all came from the cache."""
    from .icp import IcpConfig, icp
    from ...associators.dense.projective import ProjectiveAssociator

    frame = tiny_frame()
    ok = frame.valid
    points, normals = frame.vertices[ok], frame.normals[ok]
    return warm([lambda: ProjectiveAssociator().associate(points, normals, frame, np.eye(3), np.zeros(3)),
                 lambda: icp(points, normals, frame, ProjectiveAssociator(), np.eye(3), np.zeros(3),
                             IcpConfig(min_pairs=6, max_iterations=1))],
                "dense kernels", expect_s=5)
