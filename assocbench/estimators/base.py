"""The estimator interface of the closed loop, shared by every track. Each frame the harness calls::

    estimator.predict(motion)            # k > 0: odometry increment and its covariance
    problem = estimator.problem(frame)   # candidates predicted from the estimator's own mean and P
    estimator.update(association)        # the method's pairings (n,) against problem's candidates
    estimator.initialise(frame, unused)  # slam mode: unassociated features become landmarks

and reads ``pose``, ``pose_covariance``, ``landmarks``, ``covariance`` and ``book``. The estimator
never sees the truth: the harness ties map entries to true landmarks on the side
(``harness.loop_truth``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from ..association.problem import Problem
from .config import EstimatorConfig

TENTATIVE, CONFIRMED = 0, 1


@dataclass(frozen=True)
class Motion:
    """An odometry increment in the previous pose's frame and the covariance the filter is told;
    camera track: ``[Δp, Δθ]`` with ``p' = p + R Δp``, ``R' = R Exp(Δθ)``."""

    increment: np.ndarray
    covariance: np.ndarray


@dataclass(frozen=True)
class FrameData:
    """One frame's measurements ``z`` (m, d), their noise ``R`` (m, d, d) and, for an RGB-D camera,
    each feature's measured depth (m,) (NaN: none)."""

    z: np.ndarray
    R: np.ndarray
    depth: np.ndarray | None = None


@dataclass
class LandmarkBook:
    """The map's bookkeeping, one entry per landmark in state order: stable map ``ids``
    (``Problem.landmark_ids``), ``status`` (tentative or confirmed), counts ``observed`` (creation
    included) and ``missed`` (predicted in view, unassociated), and the frame it was ``born``."""

    ids: list[int] = field(default_factory=list)
    status: list[int] = field(default_factory=list)
    observed: list[int] = field(default_factory=list)
    missed: list[int] = field(default_factory=list)
    born: list[int] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.ids)

    def add(self, map_id: int, frame: int, confirmed: bool) -> None:
        """Append a landmark (observed once, at its creation)."""
        self.ids.append(map_id)
        self.status.append(CONFIRMED if confirmed else TENTATIVE)
        self.observed.append(1)
        self.missed.append(0)
        self.born.append(frame)

    def keep(self, rows: np.ndarray) -> None:
        """Keep only the entries ``rows`` (in order): the others were removed from the state."""
        for name in ("ids", "status", "observed", "missed", "born"):
            values = getattr(self, name)
            setattr(self, name, [values[r] for r in rows])

    def observe(self, rows: np.ndarray, association: np.ndarray, confirm_after: int) -> tuple[int, ...]:
        """Count an observation of each ``rows[j]`` paired; a tentative one observed
        ``confirm_after`` times is confirmed. Returns the confirmed map ids."""
        confirmed = []
        for r, f in zip(rows, association):
            if f < 0:
                continue
            self.observed[r] += 1
            if self.status[r] != CONFIRMED and self.observed[r] >= confirm_after:
                self.status[r] = CONFIRMED
                confirmed.append(self.ids[r])
        return tuple(confirmed)

    def miss(self, rows: np.ndarray, association: np.ndarray, drop_after: int) -> list[int]:
        """Count a miss of each tentative ``rows[j]`` left unassociated; returns those missed
        ``drop_after`` times (the caller removes them, then calls ``keep``)."""
        gone = []
        for r, f in zip(rows, association):
            if f < 0 and self.status[r] != CONFIRMED:
                self.missed[r] += 1
                if self.missed[r] >= drop_after:
                    gone.append(int(r))
        return gone

    @property
    def confirmed(self) -> np.ndarray:
        """Mask of confirmed entries."""
        return np.array(self.status, dtype=int) == CONFIRMED


def creation_room(cfg: EstimatorConfig, measured: int, unassociated: int, map_size: int) -> int:
    """How many landmarks a frame may make (slam): the shortfall against ``cfg.target_paired``
    pairings, capped by ``cfg.max_new_per_frame`` and the room under ``cfg.max_landmarks``; ≤ 0:
    none."""
    shortfall = cfg.target_paired - (measured - unassociated)
    return min(shortfall, cfg.max_new_per_frame, cfg.max_landmarks - map_size)


@dataclass(frozen=True)
class UpdateReport:
    """What an update did: ``paired`` pairings applied, map ids ``confirmed`` and ``removed``."""

    paired: int
    confirmed: tuple[int, ...] = ()
    removed: tuple[int, ...] = ()


class Estimator(ABC):
    """A filter (or smoother) whose posterior is the closed loop's belief."""

    book: LandmarkBook

    @abstractmethod
    def predict(self, motion: Motion) -> None:
        """Move the pose by an odometry increment; the uncertainty grows by its covariance."""

    @abstractmethod
    def problem(self, frame: FrameData) -> Problem:
        """The frame's problem: the landmarks the estimate expects to see, ``zhat`` and
        ``P = H Σ Hᵀ`` from the estimator's own mean and covariance."""

    @abstractmethod
    def update(self, association: np.ndarray) -> UpdateReport:
        """Update with ``association`` (n,) against the last ``problem``'s candidates, exactly as
        given."""

    def initialise(self, frame: FrameData, features: np.ndarray) -> list[tuple[int, int]]:
        """Make landmarks from ``features`` (unassociated feature indices); returns
        ``(map id, feature index)`` of each. Localisation makes none."""
        return []

    @property
    @abstractmethod
    def pose_covariance(self) -> np.ndarray:
        """The pose block of the covariance (q, q)."""

    @property
    @abstractmethod
    def landmarks(self) -> np.ndarray:
        """Landmark means (N, s) in ``book`` order."""

    @property
    @abstractmethod
    def covariance(self) -> np.ndarray:
        """The full covariance (q + sN, q + sN)."""
