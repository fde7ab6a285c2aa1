"""The dense track's sequence: noise-free depth and segmentation rendered along a path, cached.

Rendering is slow, so it is stored downsampled under a key of everything it depends on (scene files,
path, resolution, the sources in ``CODE``, MuJoCo's version). Noise is drawn when a frame is read,
from ``default_rng([seed, k, 17])``: the same seed gives the same frame, and noise settings change
without rendering. Entries are uncompressed archives, memory-mapped and CRC-checked on read
(``_load``): faster than inflating, at about twice the disk. The trajectory is laid out over
``max(frames, path_frames)`` frames, so frame 50 is the same view in a run of 60 frames or 200.
"""

from __future__ import annotations

import hashlib
import json
import struct
import zipfile
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from ...errors import UserError
from ...fingerprint import sources_digest
from ...models.camera import Intrinsics
from ...models.depth_frame import DepthFrame
from ...sim.cache import Unusable, cached_sequence
from ...sim.camera_path import CameraPath
from ...sim.render import FrameRenderer
from ...sim.scene import Scene, load_scene, scene_digest
from ...sources.base import SimulatedSource, short_name
from ...validation import check_number
from .depth_sensor import DepthConfig, downsample_intrinsics, sensed_frame

FORMAT_VERSION = 3   # 2: no full_size (compression counts the downsampled pixels); 3: stored, mapped, CRC-32
PATH_FRAMES = 200   # the length of the path a run's frames are taken from
DEFAULT_FRAMES = 40   # a run's frames when it names none
# the dense track's path per shipped scene when the run names none, over PATH_FRAMES frames: slow
# enough that neighbouring frames overlap as a hand-held depth camera's do (bays 2.2 cm a frame,
# crates 2 mm and 0.13 deg, plus the trajectory's seeded jitter, 1 cm and 0.5 deg); the camera
# track's own paths move 2-5x faster. On crates, frames 10 and 50 are then about 5 deg apart,
# inside ICP's capture range from the identity, and 10 and 100 about 11 deg, beyond it
# (benchmarks/dense_icp_basin.py: the homework's experiment over seeds)
DENSE_PATHS = {"room": ("circle", {"turns": 0.07}), "crates": ("circle", {"turns": 0.07}),
               "bays": ("line", {"length": 4.5}), "corridor": ("line", {"length": 4.5}),
               "checkerboard": ("line", {})}


@dataclass(frozen=True)
class DenseSequenceSpec:
    """Everything that determines a dense sequence (``depth`` noise only at read time)."""

    scene: str = "bays"
    trajectory: str | None = None
    trajectory_params: dict = field(default_factory=dict)
    frames: int = 200
    seed: int = 0
    width: int = 640
    height: int = 480
    depth: DepthConfig = field(default_factory=DepthConfig)
    path_frames: int = PATH_FRAMES

    def path(self) -> tuple[str | None, dict]:
        """The trajectory and its parameters: the run's own, else the scene's dense default."""
        if self.trajectory is None and not self.trajectory_params:
            return DENSE_PATHS.get(Path(self.scene).stem, (None, {}))
        return self.trajectory, dict(self.trajectory_params)

    def resolved_trajectory(self) -> str:
        """The path's name (the scene's default when none was given)."""
        return self.camera_path().resolved_trajectory()

    def camera_path(self) -> CameraPath:
        """The camera's path over ``max(frames, path_frames)`` frames (``sim.camera_path`` places and
        checks it); a run takes its first ``frames``."""
        name, params = self.path()
        return CameraPath(self.scene, name, params, max(self.frames, self.path_frames), self.seed, self.width,
                          self.height)

    def check(self) -> None:
        """Refuse bad settings in one line before anything renders."""
        from ...sim.trajectory import check_trajectory_params

        self.depth.check()
        check_number(self.path_frames, "dense.path_frames", integer=True, lo=2)
        for side, n in (("width", self.width), ("height", self.height)):
            if n // self.depth.downsample < 8:
                raise UserError(f"depth.downsample {self.depth.downsample} leaves a {side} of "
                                f"{n // self.depth.downsample} pixels; use a factor of at most {n // 8}")
        cam = self.camera_path()
        check_trajectory_params(cam.resolved_trajectory(), cam.trajectory_params)

    def key(self) -> str:
        """Cache key: path, frames, downsampling, scene files, format, ``CODE``'s sources, MuJoCo's
        version (not the noise)."""
        payload = {"spec": asdict(self.camera_path()), "frames": self.frames, "downsample": self.depth.downsample,
                   "scene": scene_digest(self.scene), "format": FORMAT_VERSION, "code": sources_digest(*CODE),
                   "mujoco": mujoco.__version__}
        return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:20]


@dataclass
class DenseSequence:
    """Noise-free downsampled depth (N, h, w) and geom ids, true poses, and the sensor model."""

    scene: str
    K: Intrinsics                 # of the downsampled frames
    depths: np.ndarray            # (N, h, w) float32 z-depth, NaN where nothing is hit
    geoms: np.ndarray             # (N, h, w) int32 geom id, -1 where none
    rotations: np.ndarray         # (N, 3, 3) camera-to-world
    positions: np.ndarray         # (N, 3)
    depth_cfg: DepthConfig
    seed: int
    from_cache: bool = False
    track: str = "dense"

    def __len__(self) -> int:
        return len(self.positions)

    def frame(self, k: int) -> DepthFrame:
        """Frame ``k`` as the sensor gives it: noise drawn from ``default_rng([seed, k, 17])``."""
        return sensed_frame(self.depths[k], self.geoms[k], self.rotations[k], self.positions[k],   # stored strided
                            self.K, self.depth_cfg, np.random.default_rng([self.seed, k, 17]))
# the sources a cached sequence depends on: shared simulation, measurement models, this track
CODE = ("sim", "models", "tracks/dense")
CACHE_FOLDER = "dense"       # the cache's subfolder of depth sequences


def render_dense(spec: DenseSequenceSpec, scene: Scene) -> DenseSequence:
    """Render every frame's depth and segmentation (no cache), keeping every ``downsample``-th pixel."""
    rots, pos = spec.camera_path().poses(scene)
    rots, pos = rots[:spec.frames], pos[:spec.frames]
    s = spec.depth.downsample
    # a factor that does not divide the side keeps W//s pixels (as ``depth_frame``), not ceil(W/s):
    # the strided image must be the size its intrinsics say
    h, w = spec.height // s, spec.width // s
    # filled in place: a list of frames stacked at the end would hold every frame twice at the peak
    depths = np.empty((spec.frames, h, w), np.float32)
    geoms = np.empty(depths.shape, np.int32)
    with FrameRenderer(scene, spec.width, spec.height, msaa=0) as renderer:   # depth is not blended
        for k in tqdm(range(spec.frames), desc=f"render depth {scene.name}", unit="frame", leave=False,
                      disable=None, mininterval=0.5):
            depth, geom = renderer.render_depth(rots[k], pos[k])
            depths[k] = depth[:h * s:s, :w * s:s]
            geoms[k] = geom[:h * s:s, :w * s:s]
        K_small = downsample_intrinsics(renderer.K, s)
    return DenseSequence(scene.name, K_small, depths, geoms, rots, pos, spec.depth, spec.seed)


FRAMES = ("depths", "geoms")   # the per-frame arrays: memory-mapped when read, checked by their CRC-32


def _save(seq: DenseSequence, path: Path, key: str) -> None:
    """An uncompressed archive (so ``_load`` can map its frames) with a CRC-32 of each frame array."""
    arrays = dict(key=np.array(key), scene=np.array(seq.scene),
                  K=np.array([seq.K.width, seq.K.height, seq.K.f, seq.K.cx, seq.K.cy]), depths=seq.depths,
                  geoms=seq.geoms, rotations=seq.rotations, positions=seq.positions,
                  crc=np.array([zlib.crc32(np.ascontiguousarray(getattr(seq, name))) for name in FRAMES], np.int64))
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _mapped(path: Path, archive: zipfile.ZipFile, name: str) -> np.ndarray:
    """Member ``name`` of the archive at ``path`` as a read-only memory map (past its 30-byte local
    header, name, extra field and ``.npy`` header); a truncated file fails here."""
    info = archive.getinfo(f"{name}.npy")
    if info.compress_type != zipfile.ZIP_STORED:
        raise Unusable(f"its {name} are compressed (an entry of an older format)")
    with open(path, "rb") as fh:
        fh.seek(info.header_offset)
        head = fh.read(30)
        if len(head) != 30 or head[:4] != b"PK\x03\x04":
            raise Unusable(f"the header of its {name} is damaged")
        name_len, extra_len = struct.unpack("<HH", head[26:30])
        fh.seek(info.header_offset + 30 + name_len + extra_len)
        version = np.lib.format.read_magic(fh)
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, fortran, dtype = read(fh)
        offset = fh.tell()
    return np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=shape, order="F" if fortran else "C")


def _load(path: Path, key: str, spec: DenseSequenceSpec) -> DenseSequence:
    with np.load(path, allow_pickle=False) as z:
        if str(z["key"]) != key:
            raise Unusable("it was stored under another key")
        w, h, f, cx, cy = z["K"]
        scene, rotations, positions, crc = str(z["scene"]), z["rotations"], z["positions"], z["crc"]
    with zipfile.ZipFile(path) as archive:
        depths, geoms = (_mapped(path, archive, name) for name in FRAMES)
    if [zlib.crc32(depths), zlib.crc32(geoms)] != crc.tolist():
        raise Unusable("its frames do not match their CRC-32")
    seq = DenseSequence(scene, Intrinsics(int(w), int(h), float(f), float(cx), float(cy)), depths, geoms, rotations,
                        positions, spec.depth, spec.seed, from_cache=True)
    want = (spec.frames, spec.height // spec.depth.downsample, spec.width // spec.depth.downsample)
    if seq.depths.shape != want or seq.geoms.shape != want or seq.positions.shape != (spec.frames, 3):
        raise ValueError(f"depths have shape {seq.depths.shape}, expected {want}")
    return seq


def load_dense_sequence(spec: DenseSequenceSpec, cache_dir: Path | None = None,
                        use_cache: bool = True) -> DenseSequence:
    """The sequence of ``spec`` from the cache when present and sound, else rendered and stored; a
    damaged entry is discarded with one line on stderr."""
    return cached_sequence(CACHE_FOLDER, spec.key(), lambda: render_dense(spec, load_scene(spec.scene)), _save,
                           lambda path, key: _load(path, key, spec), cache_dir, use_cache, what="depth sequence")


def dense_source(spec: DenseSequenceSpec) -> SimulatedSource:
    """The depth sequence of ``spec`` as a frame source: frame ``k`` is the sensor's noisy
    ``DepthFrame`` at the true pose (``DenseSequence.frame``)."""
    return SimulatedSource("dense", spec, short_name(spec.scene), spec.frames, DenseSequenceSpec.key,
                           load_dense_sequence, DenseSequence.frame, CACHE_FOLDER)
