"""A planar sequence: the robot's poses and, each frame, the detected posts (range-bearing with
covariance), their truth and which posts were detectable. Frame ``k``'s noise comes from
``default_rng([seed, k, 21])``: bit for bit reproducible, independent of other frames. Not cached
(cheap).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...sim.cache import storable
from ...sim.lidar import scan
from ...sim.planar_scene import PlanarScene, load_planar_scene
from ...sim.planar_trajectory import planar_trajectory
from ...sim.robot_path import PosesInPlane, ScenePath
from ...sim.scan import Scan
from ...sim.settings import LidarConfig
from .geometric_sensor import geometric_detections
from .post_detect import PostDetectorConfig, detect_posts, label_detections


@dataclass(frozen=True)
class PlanarSequenceSpec(ScenePath):
    """Everything that determines a planar sequence."""

    scene: str = "park"
    trajectory: str | None = None            # None: the scene's default (``loop`` / ``ellipse``)
    trajectory_params: dict = field(default_factory=dict)
    frames: int = 500
    seed: int = 0
    lidar: LidarConfig = field(default_factory=LidarConfig)
    posts: PostDetectorConfig = field(default_factory=PostDetectorConfig)
    keep_scans: bool = False

    def check(self) -> None:
        """Refuse a bad scene (no posts, two radii), trajectory or parameter in one line before
        anything runs."""
        planar_trajectory(load_planar_scene(self.scene), self.trajectory, min(self.frames, 2), self.seed,
                          **self.trajectory_params)


@storable
@dataclass
class PlanarSequence(PosesInPlane):
    """Per-frame detections and truth; post indices refer to ``post_names``."""

    scene: str
    posts: np.ndarray             # (L, 2)
    post_names: list[str]
    post_radius: float
    poses: np.ndarray             # (N, 3) x, y, θ
    z: list[np.ndarray]           # N x (m_k, 2) range, bearing
    R: list[np.ndarray]           # N x (m_k, 2, 2)
    labels: list[np.ndarray]      # N x (m_k,) post index or -1
    visible: np.ndarray           # (N, L) truly detectable
    max_range: float = 10.0       # the lidar's: candidates are predicted within range and field of view
    fov: float = 2 * np.pi        # rad
    nominal_R: np.ndarray = field(default_factory=lambda: np.diag([1e-4, 1e-4]))   # what a clutter detection reports
    scans: list[Scan] | None = None
    track = "planar"

    @property
    def landmarks(self) -> np.ndarray:
        return self.posts


def lidar_visible(scan_: Scan, post_geom_ids: np.ndarray, min_points: int) -> np.ndarray:
    """(L,) at least ``min_points`` beams truly hit the post in range (dropped returns included)."""
    hits = np.zeros(int(max(scan_.geom.max(), post_geom_ids.max())) + 2, int)
    np.add.at(hits, scan_.geom, 1)               # geom −1 counts in the last slot
    return hits[post_geom_ids] >= min_points


def lidar_frame(scene: PlanarScene, pose: np.ndarray, spec: PlanarSequenceSpec, rng: np.random.Generator):
    """One lidar frame: (detections, labels, visible (L,), scan)."""
    s = scan(scene, pose, spec.lidar, rng)
    det = detect_posts(s, scene.post_radius, spec.lidar.sigma_range, spec.posts)
    labels = label_detections(det, s, scene.post_geom_ids, spec.posts.min_share)
    return det, labels, lidar_visible(s, scene.post_geom_ids, spec.posts.min_points), s


def make_planar_sequence(spec: PlanarSequenceSpec, scene: PlanarScene | None = None) -> PlanarSequence:
    """Drive ``spec``'s trajectory through its scene and detect posts every frame."""
    scene = scene or load_planar_scene(spec.scene)
    poses = planar_trajectory(scene, spec.trajectory, spec.frames, spec.seed, **spec.trajectory_params)
    zs, Rs, labels, visible, scans = [], [], [], np.zeros((len(poses), len(scene.posts)), bool), []
    for k, pose in enumerate(poses):
        rng = np.random.default_rng([spec.seed, k, 21])
        if spec.lidar.mode == "geometric":
            det, lab, visible[k] = geometric_detections(scene, pose, spec.lidar, rng)
            s = None
        else:
            det, lab, visible[k], s = lidar_frame(scene, pose, spec, rng)
        zs.append(det.z)
        Rs.append(det.R)
        labels.append(lab)
        if spec.keep_scans:   # a scan is ~23 KB (720 beams): a long sequence must not hold them all
            scans.append(s)
    lidar = spec.lidar
    nominal = np.diag([lidar.sigma_range ** 2, np.deg2rad(lidar.sigma_bearing_deg) ** 2])
    return PlanarSequence(scene.name, scene.posts.copy(), list(scene.post_names), scene.post_radius, poses,
                          zs, Rs, labels, visible, lidar.max_range, np.deg2rad(lidar.fov_deg), nominal,
                          scans if spec.keep_scans else None)
