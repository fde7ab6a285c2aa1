"""A lines sequence: the robot's poses and, each frame, the lines extracted from its scan (robot
frame, with covariance), their truth and which map lines were extractable. Frame ``k`` draws its
scan noise from ``default_rng([seed, k, 31])`` and RANSAC's samples from
``default_rng([seed, k, 32])``: bit for bit reproducible, independent of other frames. Not cached
(cheap to make).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...sim.cache import storable
from ...sim.lidar import scan
from ...sim.line_scene import LineScene, beam_lines, check_scan_plane, load_line_scene, visible_lines
from ...sim.planar_trajectory import planar_trajectory
from ...sim.robot_path import PosesInPlane, ScenePath
from ...sim.scan import Scan
from ...sim.settings import LidarConfig
from .extract import LineExtractorConfig, extract_lines, label_lines


@dataclass(frozen=True)
class LineSequenceSpec(ScenePath):
    """Everything that determines a lines sequence."""

    scene: str = "office"
    trajectory: str | None = None            # None: the scene's default (``loop`` / ``ellipse``)
    trajectory_params: dict = field(default_factory=dict)
    frames: int = 500
    seed: int = 0
    lidar: LidarConfig = field(default_factory=LidarConfig)
    lines: LineExtractorConfig = field(default_factory=LineExtractorConfig)
    keep_scans: bool = False

    def check(self) -> None:
        """Refuse a bad scene (no walls, a degenerate wall or one the scan plane misses), trajectory
        or parameter in one line, before anything runs."""
        scene = load_line_scene(self.scene)
        check_scan_plane(scene, self.lidar.height)
        planar_trajectory(scene, self.trajectory, min(self.frames, 2), self.seed, **self.trajectory_params)


@storable
@dataclass
class LineSequence(PosesInPlane):
    """Per-frame extracted lines and truth; line indices refer to ``lines``."""

    scene: str
    lines: np.ndarray             # (K, 2) world (α_w, r_w), r_w ≥ 0
    segments: np.ndarray          # (S, 2, 2) world end points of each mapped wall face
    segment_line: np.ndarray      # (S,) the map line of each face
    segment_normal: np.ndarray    # (S, 2) each face's outward unit normal (seen from the front only)
    poses: np.ndarray             # (N, 3) x, y, θ
    z: list[np.ndarray]           # N x (m_k, 2) robot-frame (α, r)
    R: list[np.ndarray]           # N x (m_k, 2, 2)
    labels: list[np.ndarray]      # N x (m_k,) map line or -1
    endpoints: list[np.ndarray]   # N x (m_k, 2, 2) robot-frame segment end points
    visible: np.ndarray           # (N, K) truly extractable
    max_range: float = 10.0
    fov: float = 2 * np.pi
    nominal_R: np.ndarray = field(default_factory=lambda: np.diag([np.deg2rad(1.0) ** 2, 1e-4]))
    scans: list[Scan] | None = None
    final_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))   # the last scan's points (robot frame)
    track = "lines"

    @property
    def landmarks(self) -> np.ndarray:
        return self.lines


def line_frame(scene: LineScene, pose: np.ndarray, spec: LineSequenceSpec, k: int):
    """One frame: (detections, labels (m,), visible (K,), scan)."""
    s = scan(scene, pose, spec.lidar, np.random.default_rng([spec.seed, k, 31]))
    det = extract_lines(s, spec.lidar.sigma_range, spec.lines, np.random.default_rng([spec.seed, k, 32]))
    truth = beam_lines(scene, s, pose)
    return det, label_lines(det, truth, spec.lines.min_share), visible_lines(truth, len(scene.lines),
                                                                              spec.lines.min_points), s


def nominal_line_noise(R: list[np.ndarray], fallback: np.ndarray) -> np.ndarray:
    """What a clutter line reports without a frame of its own: ``nominal_noise`` over every
    extracted line's Σ of the sequence."""
    from ...belief.planar import nominal_noise  # here: the belief package imports the sequences

    stacked = [r.reshape(-1, 2, 2) for r in R if len(r)]
    return nominal_noise(np.concatenate(stacked), fallback) if stacked else fallback


def warm_extraction() -> None:
    """Compile or load the extraction kernels on a small synthetic wall, so the first frame does not
    wait."""
    from ...kernels import warm

    angles = np.linspace(-0.6, 0.6, 48)
    wall = Scan(angles, 2.0 / np.cos(angles), np.zeros(48, int), full_circle=False)
    warm([lambda: extract_lines(wall, 0.01, LineExtractorConfig(min_points=8))], "line extraction kernels", expect_s=2)


def make_line_sequence(spec: LineSequenceSpec, scene: LineScene | None = None) -> LineSequence:
    """Drive ``spec``'s trajectory through its scene and extract lines every frame."""
    scene = scene or load_line_scene(spec.scene)
    warm_extraction()
    poses = planar_trajectory(scene, spec.trajectory, spec.frames, spec.seed, **spec.trajectory_params)
    zs, Rs, labels, ends, scans = [], [], [], [], []
    visible = np.zeros((len(poses), len(scene.lines)), bool)
    s = None
    for k, pose in enumerate(poses):
        det, lab, visible[k], s = line_frame(scene, pose, spec, k)
        zs.append(det.z)
        Rs.append(det.R)
        labels.append(lab)
        ends.append(det.endpoints)
        if spec.keep_scans:   # a scan is ~23 KB (720 beams): a long sequence must not hold them all
            scans.append(s)
    lidar = spec.lidar
    fallback = np.diag([np.deg2rad(1.0) ** 2, lidar.sigma_range ** 2])
    return LineSequence(scene.name, scene.lines.copy(), scene.segments.copy(), scene.segment_line.copy(),
                        scene.segment_normal.copy(), poses, zs, Rs, labels, ends, visible, lidar.max_range,
                        np.deg2rad(lidar.fov_deg), nominal_line_noise(Rs, fallback),
                        scans if spec.keep_scans else None, s.points() if s is not None else np.zeros((0, 2)))
