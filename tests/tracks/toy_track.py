"""A minimal third-party track, registered from outside the package: what a user writes to add
a sensor. It claims scenes whose MJCF names a ``toy*`` site; its sensor emits synthetic problems
(``n`` landmarks on a line, a shared shift plus independent errors, clutter): no rendering, no
closed loop. Load it with ``ASSOCBENCH_TRACKS=toy_track`` and this folder on ``PYTHONPATH``.

For the tests of interrupt and resume, two environment variables (not settings: they must not
change a job's key): ``TOY_LOG`` names a file that gets a line ``seed`` each time a run's first
problem is built, ``TOY_DELAY_S`` makes building it take ``seed ×`` that many seconds; and
``TOY_WARM_LOG`` a file that gets the process id of each process that warms the track up;
``TOY_BAD_TRUTH=1`` makes the truth impossible (every landmark's true feature is feature 0);
``TOY_CLAIMS`` makes the track claim every MJCF (``all``) or raise when asked (``raise``), and
``TOY_HANG=1`` makes building frame 1's problem hang: the faults of a plugin track."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from assocbench.association.truth import FrameTruth
from assocbench.belief.config import BeliefConfig
from assocbench.errors import UserError
from assocbench.models.synthetic import lattice_problem
from assocbench.settings import Schema, Section
from assocbench.sources.base import digest, file_digest
from assocbench.tracks.base import FeatureTrack
from assocbench.tracks.capabilities import SceneMarks
from assocbench.tracks.registry import register_track
from assocbench.validation import in_range, validate_fields


@dataclass(frozen=True)
class ToySettings:
    """Section ``toy``: landmarks: how many candidates a frame has."""

    landmarks: int = field(default=12, metadata=in_range(2, 200))

    def __post_init__(self) -> None:
        validate_fields(self, "toy")


class ToySource:
    """A toy sequence as a frame source: ``frames`` frames of its scene, nothing read from disk."""

    track = "toy"

    def __init__(self, scene: str, frames: int, seed: int, landmarks: int) -> None:
        self.scene, self.frames, self.seed, self.landmarks = scene, frames, seed, landmarks
        self.name = Path(scene).stem
        self.key = digest([file_digest(scene), frames, seed, landmarks])

    def __len__(self) -> int:
        return self.frames

    def __getitem__(self, k: int) -> int:
        return k


def frame_truth(association: np.ndarray, m: int) -> FrameTruth:
    """Feature labels from the true association (feature i is landmark j where ``a[j] = i``)."""
    labels = np.full(m, -1, dtype=np.int64)
    seen = association >= 0
    labels[association[seen]] = np.flatnonzero(seen)
    return FrameTruth(labels, association, seen)


class ToyTrack(FeatureTrack):
    """Scenes with a ``toy*`` site: landmarks on a line seen by a synthetic sensor."""

    name = "toy"
    summary = "a synthetic sensor for tests: landmarks on a line, no rendering"

    def settings(self) -> Schema:
        return Schema((), {"toy": Section(ToySettings), "belief": Section(BeliefConfig)})

    def source(self, settings) -> ToySource:
        if settings.scene is None:
            raise UserError("the toy track needs a scene: an MJCF with toy* sites")
        return ToySource(str(settings.scene), settings.frames or 4, settings.seed, settings.toy.landmarks)

    def problem(self, source: ToySource, k: int, run):
        """Frame k: ``lattice_problem`` on one row, the belief's clutter, the common shift scaled by
        its ``sigma_position`` (pixels per cm), a generator seeded by (seed, k)."""
        if k == 0 and os.environ.get("TOY_LOG"):
            with open(os.environ["TOY_LOG"], "a") as log:
                log.write(f"{run.seed}\n")
        if k == 0:
            time.sleep(run.seed * float(os.environ.get("TOY_DELAY_S", "0")))
        if k == 1 and os.environ.get("TOY_HANG"):
            time.sleep(3600)
        rng = np.random.default_rng([run.seed, k])
        belief = run.belief
        problem, truth = lattice_problem(rng, n=source.landmarks, cols=source.landmarks,
                                         sigma_common=100 * belief.sigma_position, n_clutter=belief.clutter)
        if os.environ.get("TOY_BAD_TRUTH"):
            truth = np.zeros_like(truth)
        return problem, frame_truth(truth, problem.m)

    def suites(self) -> dict:
        return {}

    def scenes(self) -> dict:
        return {}

    def claims_scene(self, marks: SceneMarks) -> bool:
        claims = os.environ.get("TOY_CLAIMS")
        if claims == "raise":
            raise RuntimeError("the toy track's claim broke")
        if claims == "all":
            return True
        spec = mujoco.MjSpec.from_file(str(marks.path))
        return any(site.name.startswith("toy") for site in spec.sites)

    def warm_up(self) -> None:
        if os.environ.get("TOY_WARM_LOG"):
            with open(os.environ["TOY_WARM_LOG"], "a") as log:
                log.write(f"{os.getpid()}\n")


register_track(ToyTrack)
