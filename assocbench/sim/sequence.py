"""A rendered sequence: poses, features, truth labels and visibility of every frame, cached.

``load_sequence(spec)`` renders, detects and labels each frame once and stores the result
under a key that hashes everything that affects it (scene files, trajectory, resolution,
detector and truth settings, this module's format version). A second call with the same
spec reads the cache and renders nothing.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..atomic import atomic_path
from ..errors import UserError
from .camera import Intrinsics
from .detect import DetectorConfig, detect
from .render import FrameRenderer
from .scene import Scene, load_scene
from .trajectory import TRAJECTORIES, make_trajectory, rig_for
from .truth import TruthConfig, label_features, visibility

FORMAT_VERSION = 3
DEFAULT_TRAJECTORY = {"room": "circle", "checkerboard": "line", "corridor": "line"}


def default_cache_dir() -> Path:
    """``$ASSOCBENCH_CACHE`` or ``~/.cache/assocbench``."""
    return Path(os.environ.get("ASSOCBENCH_CACHE", Path.home() / ".cache" / "assocbench"))


@dataclass(frozen=True)
class SequenceSpec:
    """Everything that determines a rendered sequence."""

    scene: str = "room"
    trajectory: str | None = None           # None: the scene's default
    frames: int = 40
    seed: int = 0
    width: int = 640
    height: int = 480
    trajectory_params: dict = field(default_factory=dict)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    truth: TruthConfig = field(default_factory=TruthConfig)
    keep_images: bool = False

    def resolved_trajectory(self) -> str:
        name = self.trajectory or DEFAULT_TRAJECTORY.get(Path(self.scene).stem, "circle")
        if name not in TRAJECTORIES:
            raise UserError(f"unknown trajectory {name!r}: choose one of {', '.join(TRAJECTORIES)}")
        return name

    def key(self, scene: Scene) -> str:
        payload = asdict(self) | {"trajectory": self.resolved_trajectory(), "scene": scene.digest,
                                  "format": FORMAT_VERSION}
        return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:20]


@dataclass
class Sequence:
    """Rendered frames' truth. Landmark indices refer to ``landmark_names``."""

    scene: str
    K: Intrinsics
    landmarks: np.ndarray          # (L, 3)
    normals: np.ndarray            # (L, 3) outward unit normals
    landmark_names: list[str]
    rotations: np.ndarray          # (N, 3, 3) camera-to-world, OpenCV axes
    positions: np.ndarray          # (N, 3)
    features: list[np.ndarray]     # N x (m_k, 2) detected pixels
    labels: list[np.ndarray]       # N x (m_k,) landmark index or -1
    visible: np.ndarray            # (N, L) truly visible
    projections: np.ndarray        # (N, L, 2) true projections
    images: np.ndarray | None = None
    from_cache: bool = False

    def __len__(self) -> int:
        return len(self.positions)


def render_sequence(spec: SequenceSpec, scene: Scene | None = None) -> Sequence:
    """Render, detect and label every frame of ``spec`` (no cache)."""
    scene = scene or load_scene(spec.scene)
    rig = rig_for(scene.landmarks, scene.normals, scene.fovy, spec.width / spec.height)
    rots, pos = make_trajectory(spec.resolved_trajectory(), rig, spec.frames, spec.seed, **spec.trajectory_params)
    feats, labels, vis, proj, images = [], [], [], [], []
    need_depth = spec.truth.occlusion == "depth"
    with FrameRenderer(scene, spec.width, spec.height) as renderer:
        for k in tqdm(range(spec.frames), desc=f"render {scene.name}", unit="frame", leave=False,
                      disable=None, mininterval=0.5):  # shown on a terminal only
            frame = renderer.render(rots[k], pos[k], depth=need_depth)
            rng = np.random.default_rng([spec.seed, k, 11])
            f = detect(frame["rgb"], spec.detector, rng)
            uv, imaged, visible = visibility(scene, rots[k], pos[k], renderer.K, spec.truth, frame.get("depth"))
            feats.append(f)
            labels.append(label_features(f, uv, imaged, spec.truth.gate_px))
            vis.append(visible)
            proj.append(uv)
            if spec.keep_images:
                images.append(frame["rgb"])
        K = renderer.K
    return Sequence(scene.name, K, scene.landmarks, scene.normals, scene.landmark_names, rots, pos, feats, labels,
                    np.array(vis), np.array(proj), np.array(images) if spec.keep_images else None)


def _save(seq: Sequence, path: Path) -> None:
    counts = np.array([len(f) for f in seq.features])
    arrays = dict(
        K=np.array([seq.K.width, seq.K.height, seq.K.f, seq.K.cx, seq.K.cy]),
        landmarks=seq.landmarks, normals=seq.normals, names=np.array(seq.landmark_names), scene=np.array(seq.scene),
        rotations=seq.rotations, positions=seq.positions, counts=counts,
        features=np.concatenate(seq.features) if counts.sum() else np.zeros((0, 2)),
        labels=np.concatenate(seq.labels) if counts.sum() else np.zeros(0, np.int64),
        visible=seq.visible, projections=seq.projections,
    )
    if seq.images is not None:
        arrays["images"] = seq.images
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)


def _load(path: Path) -> Sequence:
    with np.load(path) as z:
        w, h, f, cx, cy = z["K"]
        splits = np.cumsum(z["counts"])[:-1]
        return Sequence(
            str(z["scene"]), Intrinsics(int(w), int(h), float(f), float(cx), float(cy)),
            z["landmarks"], z["normals"], [str(n) for n in z["names"]], z["rotations"], z["positions"],
            np.split(z["features"], splits), np.split(z["labels"], splits), z["visible"],
            z["projections"], z["images"] if "images" in z.files else None, from_cache=True,
        )


def load_sequence(spec: SequenceSpec, cache_dir: Path | None = None, use_cache: bool = True) -> Sequence:
    """The sequence of ``spec``: from the cache when present, else rendered and stored."""
    scene = load_scene(spec.scene)
    path = Path(cache_dir or default_cache_dir()) / "sequences" / f"{spec.key(scene)}.npz"
    if use_cache and path.is_file():
        try:
            return _load(path)
        except (OSError, ValueError, KeyError):
            pass  # a damaged cache entry is rebuilt below
    seq = render_sequence(spec, scene)
    if use_cache:
        _save(seq, path)
    return seq
