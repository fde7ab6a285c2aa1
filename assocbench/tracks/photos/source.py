"""The photos track's frame source: a Bundler reconstruction with its images and SIFT key files, one
frame per image, read from the installed ``gtsam`` package (never copied). Balbianello:
``gtsam/Data/Balbianello.out`` and ``Balbianello/BalbianelloMedium-{1..5}.jpg`` with a ``.key.gz``
each; camera ``c`` is image ``c + 1``."""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import UserError
from ...fingerprint import sources_digest
from ...models.bundler import BundlerCamera
from ...sources.base import digest, file_digest
from .recording import Photo, Recording

TRACK = "photos"
GTSAM = "gtsam is not installed (pip install 'assocbench[gtsam]'; from a clone: pip install '.[gtsam]')"
CODE = ("models", "tracks/photos")   # the sources the frames depend on


@dataclass(frozen=True)
class PhotoSet:
    """What a reconstruction is made of: its ``name``, the ``bundle`` file, and per camera of the
    bundle its image and its key file."""

    name: str
    bundle: Path
    images: tuple[Path, ...]
    keys: tuple[Path, ...]

    def files(self) -> tuple[Path, ...]:
        """Every file the frames are read from."""
        return (self.bundle, *self.images, *self.keys)


def gtsam_data() -> Path | None:
    """The ``Data`` folder of the installed ``gtsam`` package (found without importing it), or None."""
    spec = importlib.util.find_spec("gtsam")
    if spec is None or not spec.origin:
        return None
    return Path(spec.origin).parent / "Data"


def balbianello() -> PhotoSet:
    """Balbianello as the ``gtsam`` wheel ships it; a one-line error where it is not installed."""
    data = gtsam_data()
    if data is None:
        raise UserError(f"the photos track reads Balbianello from the gtsam package: {GTSAM}")
    folder = data / "Balbianello"
    images = tuple(folder / f"BalbianelloMedium-{c}.jpg" for c in range(1, 6))
    found = PhotoSet("balbianello", data / "Balbianello.out", images, tuple(i.with_suffix(".key.gz") for i in images))
    missing = [str(f) for f in found.files() if not f.is_file()]
    if missing:
        raise UserError(f"this gtsam has no Balbianello ({missing[0]} is missing): install gtsam>=4.2")
    return found


@dataclass(frozen=True)
class PhotoFrame:
    """Frame ``index``: its ``photo``, the map's ``landmarks`` (L, 3), ``in_map`` (seen with a
    keypoint elsewhere) and their ``descriptors`` from the other images."""

    index: int
    photo: Photo
    landmarks: np.ndarray
    in_map: np.ndarray
    descriptors: np.ndarray


class PhotoSource:
    """A reconstruction as a frame source, read and matched once per process on first read; pickling
    drops it."""

    track = TRACK

    def __init__(self, photos: PhotoSet, frames: int, match_radius: float) -> None:
        self.photos, self.name, self.match_radius = photos, photos.name, float(match_radius)
        self.frames = int(frames)
        self._key: str | None = None
        self._recording: Recording | None = None

    @property
    def key(self) -> str:
        if self._key is None:
            self._key = digest([[file_digest(f) for f in self.photos.files()], self.frames, self.match_radius,
                                sources_digest(*CODE)])
        return self._key

    def recording(self) -> Recording:
        """The reconstruction, read and matched once."""
        if self._recording is None:
            self._recording = read_recording(self.photos, self.match_radius)
        return self._recording

    def __len__(self) -> int:
        return self.frames

    def __getitem__(self, k: int) -> PhotoFrame:
        if not 0 <= k < self.frames:
            raise IndexError(f"frame {k} of a {self.frames}-frame source")
        rec = self.recording()
        descriptors, has = rec.landmark_descriptors(k)
        return PhotoFrame(k, rec.photos[k], rec.landmarks, has, descriptors)

    def __getstate__(self) -> dict:
        return self.__dict__ | {"_recording": None}

    def __repr__(self) -> str:
        return f"PhotoSource({self.name}, {self.frames} frames)"


def read_recording(photos: PhotoSet, match_radius: float) -> Recording:
    """Read the bundle, the key files and the image sizes, and match them (``recording``)."""
    import cv2

    from .files import read_bundle, read_keys
    from .recording import build_recording

    bundle = read_bundle(photos.bundle)
    if len(bundle.cameras) != len(photos.images):
        raise UserError(f"{photos.bundle} has {len(bundle.cameras)} cameras for {len(photos.images)} images")
    cameras = []
    for cam, image in zip(bundle.cameras, photos.images):
        pixels = cv2.imread(str(image), cv2.IMREAD_UNCHANGED)
        if pixels is None:
            raise UserError(f"cannot read the image {image}")
        cameras.append(BundlerCamera(cam.f, cam.k1, cam.k2, cam.R, cam.t, pixels.shape[1], pixels.shape[0]))
    keys = [read_keys(k) for k in photos.keys]
    return build_recording(bundle, keys, list(photos.images), cameras, match_radius)
