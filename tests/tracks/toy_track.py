"""A minimal third-party track, registered from outside the package: what a user writes to add
a sensor. It claims scenes whose MJCF names a ``toy*`` site; its sensor emits synthetic problems
(``n`` landmarks on a line, a shared shift plus independent errors, clutter): no rendering, no
closed loop. Load it with ``ASSOCBENCH_TRACKS=toy_track`` and this folder on ``PYTHONPATH``.

For the tests of interrupt and resume, two environment variables (not settings: they must not
change a job's key): ``TOY_LOG`` names a file that gets a line ``seed`` each time a sequence's
problems are built, ``TOY_DELAY_S`` makes building them take ``seed ×`` that many seconds; and
``TOY_WARM_LOG`` a file that gets the process id of each process that warms the track up;
``TOY_BAD_TRUTH=1`` makes the truth impossible (every landmark's true feature is feature 0)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import mujoco
import numpy as np

from assocbench.association.truth import FrameTruth
from assocbench.models.synthetic import lattice_problem
from assocbench.tracks.base import SceneMarks, Track, register_track
from assocbench.validation import check_number


@dataclass(frozen=True)
class ToySpec:
    """What determines a toy sequence."""

    scene: str
    frames: int
    seed: int
    landmarks: int

    def resolved_trajectory(self) -> str:
        return "none"


@dataclass(frozen=True)
class ToySequence:
    spec: ToySpec
    track: str = "toy"

    def __len__(self) -> int:
        return self.spec.frames


def frame_truth(association: np.ndarray, m: int) -> FrameTruth:
    """Feature labels from the true association (feature i is landmark j where ``a[j] = i``)."""
    labels = np.full(m, -1, dtype=np.int64)
    seen = association >= 0
    labels[association[seen]] = np.flatnonzero(seen)
    return FrameTruth(labels, association, seen)


class ToyTrack(Track):
    """Scenes with a ``toy*`` site: landmarks on a line seen by a synthetic sensor."""

    name = "toy"
    summary = "a synthetic sensor for tests: landmarks on a line, no rendering"
    spec_type = ToySpec

    def claims_scene(self, marks: SceneMarks) -> bool:
        spec = mujoco.MjSpec.from_file(str(marks.path))
        return any(site.name.startswith("toy") for site in spec.sites)

    def config_sections(self) -> dict[str, dict]:
        return {"toy": {"landmarks": 12}}

    def warm_up(self) -> None:
        if os.environ.get("TOY_WARM_LOG"):
            with open(os.environ["TOY_WARM_LOG"], "a") as log:
                log.write(f"{os.getpid()}\n")

    def sequence_spec(self, cfg: dict, estimator) -> ToySpec:
        n = check_number(cfg["toy"]["landmarks"], "toy.landmarks", integer=True, lo=2, hi=200)
        return ToySpec(str(cfg["scene"]), int(cfg["frames"]), int(cfg["seed"]), n)

    def load_sequence(self, spec: ToySpec, cache_dir=None, use_cache: bool = True) -> ToySequence:
        return ToySequence(spec)

    def problems(self, seq: ToySequence, belief, seed: int) -> list:
        """Frame k: ``lattice_problem`` on one row, the belief's clutter, the common shift scaled by
        its ``sigma_position`` (pixels per cm), a generator seeded by (seed, k)."""
        if os.environ.get("TOY_LOG"):
            with open(os.environ["TOY_LOG"], "a") as log:
                log.write(f"{seed}\n")
        time.sleep(seed * float(os.environ.get("TOY_DELAY_S", "0")))
        out = []
        for k in range(len(seq)):
            rng = np.random.default_rng([seed, k])
            problem, truth = lattice_problem(rng, n=seq.spec.landmarks, cols=seq.spec.landmarks,
                                             sigma_common=100 * belief.sigma_position, n_clutter=belief.clutter)
            if os.environ.get("TOY_BAD_TRUTH"):
                truth = np.zeros_like(truth)
            out.append((problem, frame_truth(truth, problem.m)))
        return out


register_track(ToyTrack)
