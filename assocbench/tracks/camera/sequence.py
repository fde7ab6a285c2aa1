"""A rendered sequence: poses, features, truth labels and visibility of every frame, rendered once
and cached under a key hashing all it depends on (scene files, trajectory, resolution, detector and
truth settings, format version, the sources in ``CODE``, MuJoCo and OpenCV versions).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import ClassVar

import cv2
import mujoco
import numpy as np
from tqdm import tqdm

from ..._runtime import cache_root
from ...fingerprint import sources_digest
from ...models.camera import Intrinsics
from ...sim.cache import Unusable, cached_sequence
from ...sim.camera_path import CameraPath
from ...sim.render import FrameRenderer
from ...sim.scene import Scene, load_scene, resolve_scene_path, scene_digest
from ...sim.waypoints import waypoint_digest
from ...sources.base import SimulatedSource, short_name
from .detect import detect
from .settings import DetectorConfig, TruthConfig
from .truth import label_features, visibility

FORMAT_VERSION = 5  # 5: optional rendered depth at each feature (RGB-D, for the closed loop's SLAM)
# the sources a cached sequence depends on: shared simulation, measurement models, this track
CODE = ("sim", "models", "tracks/camera")
CACHE_FOLDER = "sequences"   # the cache's subfolder of camera sequences (the first track's, named before tracks were)


def default_cache_dir() -> Path:
    """``$ASSOCBENCH_CACHE`` or ``~/.cache/assocbench``."""
    return cache_root()


@dataclass(frozen=True)
class SequenceSpec:
    """Everything that determines a rendered sequence."""

    scene: str = "room"
    trajectory: str | None = None           # None: the scene's default
    frames: int = 40
    seed: int = 0
    width: int = 640
    height: int = 480
    msaa: int | None = None                  # None: the scene's own multisampling
    trajectory_params: dict = field(default_factory=dict)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    truth: TruthConfig = field(default_factory=TruthConfig)
    keep_images: bool = False
    feature_depth: bool = False             # render depth and keep its value at each feature (RGB-D)

    def path(self) -> CameraPath:
        """The camera's path (``sim.camera_path``)."""
        return CameraPath(self.scene, self.trajectory, self.trajectory_params, self.frames, self.seed, self.width,
                          self.height)

    def resolved_trajectory(self) -> str:
        """The trajectory's name (the scene's default when None), checked (``CameraPath``)."""
        return self.path().resolved_trajectory()

    def key(self) -> str:
        """Cache key: every setting, the scene's files, a waypoint file's content, the format,
        ``CODE``'s sources, MuJoCo and OpenCV versions."""
        path = resolve_scene_path(self.scene)
        payload = asdict(self) | {"trajectory": self.resolved_trajectory(), "scene": scene_digest(path),
                                  "format": FORMAT_VERSION, "code": sources_digest(*CODE),
                                  "mujoco": mujoco.__version__, "opencv": cv2.__version__}
        if payload["trajectory"] == "waypoints":
            payload["waypoints"] = waypoint_digest("waypoints", self.trajectory_params, path)
        return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:20]


@dataclass
class Sequence:
    """Rendered frames' truth. Landmark indices refer to ``landmark_names``."""

    track: ClassVar[str] = "camera"   # the registered track that reads it

    scene: str
    K: Intrinsics
    landmarks: np.ndarray          # (L, 3)
    normals: np.ndarray            # (L, 3) outward unit normals
    landmark_names: list[str]
    rotations: np.ndarray          # (N, 3, 3) camera-to-world, OpenCV axes
    positions: np.ndarray          # (N, 3)
    features: list[np.ndarray]     # N x (m_k, 2) detected pixels
    labels: list[np.ndarray]       # N x (m_k,) landmark index or -1
    visible: np.ndarray            # (N, L) truly visible: imaged, the only landmarks labels name
    projections: np.ndarray        # (N, L, 2) true projections
    depths: list[np.ndarray] | None = None   # N x (m_k,) rendered z-depth at each feature, NaN where none
    images: np.ndarray | None = None
    from_cache: bool = False

    def __len__(self) -> int:
        return len(self.positions)


@dataclass
class RenderedFrame:
    """One rendered frame, its detections and their truth (what ``render_sequence`` keeps)."""

    rgb: np.ndarray | None   # dropped once a sequence has taken what it keeps
    features: np.ndarray     # (m, 2)
    labels: np.ndarray       # (m,) landmark index or -1
    projections: np.ndarray  # (L, 2)
    visible: np.ndarray      # (L,) in front, in the image, front side towards the camera, unoccluded
    depths: np.ndarray | None = None   # (m,) rendered z-depth at each feature (``feature_depth``)


def trajectory_poses(spec: SequenceSpec, scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Camera rotations (N, 3, 3) and positions (N, 3) of ``spec``'s trajectory in ``scene``."""
    return spec.path().poses(scene)


def process_frame(spec: SequenceSpec, scene: Scene, renderer: FrameRenderer, R: np.ndarray, p: np.ndarray,
                  k: int) -> RenderedFrame:
    """Render frame ``k`` at pose ``(R, p)``, detect its features and label them."""
    frame = renderer.render(R, p, depth=spec.truth.occlusion == "depth" or spec.feature_depth)
    features = detect(frame["rgb"], spec.detector, np.random.default_rng([spec.seed, k, 11]))
    uv, visible = visibility(scene, R, p, renderer.K, spec.truth, frame.get("depth"))
    labels = label_features(features, uv, visible, spec.truth.gate_px)
    depths = depth_at(frame["depth"], features, renderer.far) if spec.feature_depth else None
    return RenderedFrame(frame["rgb"], features, labels, uv, visible, depths)


def depth_at(depth: np.ndarray, features: np.ndarray, far: float) -> np.ndarray:
    """Rendered z-depth at each feature's nearest pixel (one surface's value, not a blend); NaN
    where nothing was hit or not a positive finite number."""
    cols = np.clip(np.rint(features[:, 0]).astype(int), 0, depth.shape[1] - 1)
    rows = np.clip(np.rint(features[:, 1]).astype(int), 0, depth.shape[0] - 1)
    z = depth[rows, cols].astype(np.float64)
    return np.where(np.isfinite(z) & (z > 0) & (z < 0.999 * far), z, np.nan)


def render_sequence(spec: SequenceSpec, scene: Scene | None = None) -> Sequence:
    """Render, detect and label every frame of ``spec`` (no cache)."""
    scene = scene or load_scene(spec.scene)
    rots, pos = trajectory_poses(spec, scene)
    frames, images = [], []
    with FrameRenderer(scene, spec.width, spec.height, spec.msaa) as renderer:
        for k in tqdm(range(spec.frames), desc=f"render {scene.name}", unit="frame", leave=False,
                      disable=None, mininterval=0.5):  # the bar shows on a terminal only
            f = process_frame(spec, scene, renderer, rots[k], pos[k], k)
            if spec.keep_images:
                images.append(f.rgb)
            f.rgb = None  # a long sequence must not hold every image in memory
            frames.append(f)
        K = renderer.K
    return Sequence(scene.name, K, scene.landmarks, scene.normals, scene.landmark_names, rots, pos,
                    [f.features for f in frames], [f.labels for f in frames],
                    np.array([f.visible for f in frames]), np.array([f.projections for f in frames]),
                    [f.depths for f in frames] if spec.feature_depth else None,
                    np.array(images) if spec.keep_images else None)


def _save(seq: Sequence, path: Path, key: str) -> None:
    """Write ``seq`` with its cache ``key`` inside, so an entry under another key is recognised."""
    counts = np.array([len(f) for f in seq.features])
    arrays = dict(
        key=np.array(key),
        K=np.array([seq.K.width, seq.K.height, seq.K.f, seq.K.cx, seq.K.cy]),
        landmarks=seq.landmarks, normals=seq.normals, names=np.array(seq.landmark_names), scene=np.array(seq.scene),
        rotations=seq.rotations, positions=seq.positions, counts=counts,
        features=np.concatenate(seq.features) if counts.sum() else np.zeros((0, 2)),
        labels=np.concatenate(seq.labels) if counts.sum() else np.zeros(0, np.int64),
        visible=seq.visible, projections=seq.projections,
    )
    if seq.images is not None:
        arrays["images"] = seq.images
    if seq.depths is not None:
        arrays["depths"] = np.concatenate(seq.depths) if counts.sum() else np.zeros(0)
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def _load(path: Path, key: str, spec: SequenceSpec) -> Sequence:
    """Read a cache entry and check it is the sequence of ``key``; raise one of ``cache.DAMAGED``."""
    with np.load(path, allow_pickle=False) as z:
        if "key" not in z.files or str(z["key"]) != key:
            raise Unusable("it was stored under another key")
        w, h, f, cx, cy = z["K"]
        counts = z["counts"]
        splits = np.cumsum(counts)[:-1]
        seq = Sequence(
            str(z["scene"]), Intrinsics(int(w), int(h), float(f), float(cx), float(cy)),
            z["landmarks"], z["normals"], [str(n) for n in z["names"]], z["rotations"], z["positions"],
            np.split(z["features"], splits), np.split(z["labels"], splits), z["visible"],
            z["projections"], np.split(z["depths"], splits) if "depths" in z.files else None,
            z["images"] if "images" in z.files else None, from_cache=True,
        )
    _check_shapes(seq, counts, spec)
    return seq


def _check_shapes(seq: Sequence, counts: np.ndarray, spec: SequenceSpec) -> None:
    """Raise ``Unusable`` unless every array has the shape ``spec`` implies."""
    n, lms = spec.frames, len(seq.landmark_names)
    features = np.concatenate(seq.features) if len(seq.features) else np.zeros((0, 2))
    labels = np.concatenate(seq.labels) if len(seq.labels) else np.zeros(0, np.int64)
    expected = {"rotations": (seq.rotations.shape, (n, 3, 3)), "positions": (seq.positions.shape, (n, 3)),
                "counts": (counts.shape, (n,)), "landmarks": (seq.landmarks.shape, (lms, 3)),
                "normals": (seq.normals.shape, (lms, 3)), "visible": (seq.visible.shape, (n, lms)),
                "projections": (seq.projections.shape, (n, lms, 2)),
                "features": (features.shape, (int(counts.sum()), 2)), "labels": (labels.shape, (int(counts.sum()),)),
                "image size": ((seq.K.width, seq.K.height), (spec.width, spec.height)),
                "images": (None if seq.images is None else seq.images.shape,
                           (n, spec.height, spec.width, 3) if spec.keep_images else None),
                "depths": (None if seq.depths is None else (sum(len(d) for d in seq.depths),),
                           (int(counts.sum()),) if spec.feature_depth else None)}
    for name, (got, want) in expected.items():
        if got != want:
            raise Unusable(f"{name} has shape {got}, expected {want}")
    if labels.size and (labels.min() < -1 or labels.max() >= lms):
        raise Unusable("a label names no landmark")


def load_sequence(spec: SequenceSpec, cache_dir: Path | None = None, use_cache: bool = True) -> Sequence:
    """The sequence of ``spec`` from the cache when present and sound, else rendered and stored."""
    return cached_sequence(CACHE_FOLDER, spec.key(), lambda: render_sequence(spec), _save,
                           lambda path, key: _load(path, key, spec), cache_dir, use_cache)


def sequence_frame(seq: Sequence, k: int) -> dict:
    """Frame ``k``: the pose, detected features and labels, the truly visible landmarks and their
    projections."""
    return {"R": seq.rotations[k], "p": seq.positions[k], "features": seq.features[k], "labels": seq.labels[k],
            "visible": seq.visible[k], "projections": seq.projections[k]}


def camera_source(spec: SequenceSpec) -> SimulatedSource:
    """The rendered sequence of ``spec`` as a frame source (rendered or read from the cache when
    first read; keyed by ``SequenceSpec.key``)."""
    return SimulatedSource("camera", spec, short_name(spec.scene), spec.frames, SequenceSpec.key, load_sequence,
                           sequence_frame, CACHE_FOLDER)
