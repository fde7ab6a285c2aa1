"""The photos track: real photographs, their SIFT keypoints, and a Bundler map predicted into each
through a perturbed camera, scored against the reconstruction's own reference association. Light to
import."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ...errors import UserError
from ...settings import Schema, Section, Settings
from ..base import Columns, FeatureTrack, SuiteFile
from .settings import PhotoBelief, PhotoSettings

SUITES = {"real_photos": False}   # name -> guarded by check
# the belief of a fixed set of photos: no clutter is added (the keypoints are clutter enough) and
# the candidates are what the estimated camera sees in front of it, whatever their facing
BELIEF = Section(PhotoBelief, exclude=("clutter", "max_view_angle"))


class PhotosTrack(FeatureTrack):
    """Recorded photos with SIFT keypoints and a Bundler reconstruction (Balbianello, in gtsam's data)."""

    name = "photos"
    data_licence = ("the photos, SIFT keys and Bundler reconstruction are Balbianello as the gtsam package ships it "
                    "(gtsam/Data, under gtsam's licence); the beliefs and the reference matching made from them by "
                    "assocbench: MIT (LICENSE)")
    summary = ("real photos (Balbianello, from the gtsam package): every SIFT keypoint against a Bundler map "
               "predicted through a perturbed camera, scored against the reconstruction's reference")

    # --- core ----------------------------------------------------------------------------
    def settings(self) -> Schema:
        return Schema((), {"belief": BELIEF, "photos": Section(PhotoSettings)})

    def source(self, settings: Settings) -> Any:
        """One frame per image of the reconstruction the scene names (``balbianello``)."""
        from .source import PhotoSource, balbianello

        scene = settings.scene or next(iter(self.scenes()))
        if scene != "balbianello":
            raise UserError(f"the photos track reads the reconstruction 'balbianello', not {scene!r}")
        photos = balbianello()
        frames = settings.frames or len(photos.images)
        if frames > len(photos.images):
            raise UserError(f"frames {frames}: {photos.name} has {len(photos.images)} images, one frame each")
        return PhotoSource(photos, frames, settings.photos.match_radius)

    def problem(self, source: Any, k: int, run: Any):
        from .belief import make_photo_problem

        return make_photo_problem(source[k], run.belief, run.seed)

    def columns(self, loop: bool) -> Columns:
        """The shared columns, scored against the reconstruction's reference, not a truth."""
        return replace(super().columns(loop), scored_against="reference")

    def suites(self) -> dict[str, SuiteFile]:
        from ...configs import shipped_config

        return {name: SuiteFile(shipped_config(f"{name}.yaml"), ci) for name, ci in SUITES.items()}

    def scenes(self) -> dict[str, str]:
        return {"balbianello": "5 photos (640x427) of a villa's facade, 1 783-2 455 SIFT keys each, a Bundler "
                               "reconstruction of 544 points (gtsam's Data)"}

    # --- capabilities ----------------------------------------------------------------------
    def unavailable(self) -> str | None:
        """Without ``gtsam`` there is no Balbianello to read."""
        from .source import GTSAM, gtsam_data

        return GTSAM if gtsam_data() is None else None

    def frame_picture(self, run: Any, index: int) -> tuple[np.ndarray, str]:
        from .pictures import frame_picture

        return frame_picture(run, index)

    def run_pictures(self, run: Any, source: Any, frames):
        from .pictures import run_pictures

        return run_pictures(run, source, frames)
