"""Load or compile the dense kernels once per process, on tiny inputs (``kernels.warm``)."""

from __future__ import annotations

from functools import cache

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
    """Run every dense kernel once on a tiny frame, so they are loaded or compiled (one line on
    stderr) before anything is timed. Returns the seconds compiling, None when all were cached."""
    from ...associators.dense.projective import ProjectiveAssociator
    from .depth_sensor import DepthConfig, sensed_frame
    from .fusion import FusionConfig, PointMap, fuse
    from .icp import IcpConfig, direction_share, icp
    from .metrics import score_associations
    from .picture_json import fixed_json
    from .prediction import Splatter, predict
    from .run import view_source
    from .surface import warm_surface

    @cache
    def tiny():   # built inside the warm-up: normal_map's kernel is one of those it announces
        frame = tiny_frame()
        ok = frame.valid
        return frame, ok, frame.vertices[ok], frame.normals[ok]

    def associate():
        frame, _, points, normals = tiny()
        return ProjectiveAssociator().associate(points, normals, frame, np.eye(3), np.zeros(3))

    def one_icp():
        frame, _, points, normals = tiny()
        return icp(points, normals, frame, ProjectiveAssociator(), np.eye(3), np.zeros(3),
                   IcpConfig(min_pairs=6, max_iterations=1))

    def share():
        frame, _, points, normals = tiny()
        return direction_share(points, normals, associate(), frame, np.eye(3), np.zeros(3))

    def score():
        frame, ok, points, _ = tiny()
        return score_associations(frame.true_points[ok], frame.geom[ok], frame,
                                  [(np.arange(len(points)), np.flatnonzero(ok.reshape(-1)))], 0.03)

    pmap, fusion = PointMap(), FusionConfig(dormant_frames=1, stable_weight=10)
    return warm([associate, one_icp, share,
                 lambda: [fuse(pmap, tiny()[0], np.eye(3), np.zeros(3), k, fusion) for k in range(3)],
                 lambda: predict(pmap.positions, pmap.weights, tiny()[0].K, np.eye(3), np.zeros(3)),
                 lambda: view_source(pmap, Splatter(tiny()[0].K), np.eye(3), np.zeros(3)),
                 warm_surface, score, lambda: fixed_json(np.array([[1.5, -0.25, np.nan, np.inf]])),
                 lambda: sensed_frame(np.ones((6, 6), np.float32), np.zeros((6, 6), np.int32), np.eye(3), np.zeros(3),
                                      tiny()[0].K, DepthConfig(dropout=0.1), np.random.default_rng(0))],
                "dense kernels", expect_s=20)
