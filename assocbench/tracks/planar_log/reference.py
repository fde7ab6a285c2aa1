"""The reference solution of a recorded range-bearing log: every pose and reference landmark fitted
with GTSAM to the log's odometry and referenced sightings (its own association), computed once per
log file and cached. It is a reference, not ground truth: what the log's association implies.

How: batch Levenberg–Marquardt from dead reckoning stops in a wrong minimum on Victoria Park, so an
iSAM2 pass comes first (``BATCH`` poses at a time, each new pose and landmark initialised from
the estimate), then Levenberg–Marquardt polishes the whole graph. Factors:
``BetweenFactorPose2`` per increment (the file's covariance), ``BearingRangeFactor2D`` per
referenced sighting (``R = G Σ Gᵀ``, bearing first), a prior fixing the first pose at the origin
(``GAUGE_SIGMA``: the gauge); unreferenced sightings are left out.

Fit: ``chi2 = Σ‖whitened residual‖²`` at the optimum; ``dof`` = measurement dims − (variable dims −
3); ``chi2 / dof`` near 1 says the log's covariances describe its residuals. ``outliers``:
referenced sightings past χ²₂(0.999).
"""

from __future__ import annotations

import importlib.metadata
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import chi2 as chi2_dist

from ...fingerprint import PACKAGE_ROOT, files_digest
from ...sim.cache import storable
from ...sources.base import digest
from ...sources.range_bearing_log import RangeBearingLog

BATCH = 50               # poses per iSAM2 update (one pose an update reaches the same optimum, far slower)
GAUGE_SIGMA = 1e-6       # m, rad: the first pose's prior
OUTLIER_LEVEL = 0.999    # a sighting whose χ²₂ exceeds this quantile is counted in ``outliers``
CODE = ("tracks/planar_log/reference.py", "sources/range_bearing_log.py")   # what the cached solution depends on
CACHE_FOLDER = "planar_log"


@storable
@dataclass(frozen=True)
class ReferenceSolution:
    """A log's reference path and map. poses: (N, 3). ids: (L,) reference ids by first sighting.
    landmarks: (L, 2) (m). chi2, dof: the fit. outliers: referenced sightings past χ²₂(0.999).
    sightings: those fitted. iterations: Levenberg–Marquardt's."""

    poses: np.ndarray
    ids: np.ndarray
    landmarks: np.ndarray
    chi2: float
    dof: int
    outliers: int
    sightings: int
    iterations: int

    @property
    def chi2_dof(self) -> float:
        """χ² per degree of freedom at the optimum."""
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    def index_of(self, refs: np.ndarray) -> np.ndarray:
        """Each reference id's index into ``ids`` (−1 for none or an id the solution lacks)."""
        lookup = {int(r): j for j, r in enumerate(self.ids)}
        return np.array([lookup.get(int(r), -1) for r in np.asarray(refs).reshape(-1)], dtype=np.int64)

    def describe(self) -> str:
        """One line: how it was made and how well it fits."""
        return (f"GTSAM iSAM2 ({BATCH} poses an update) then Levenberg-Marquardt ({self.iterations} iterations) "
                f"with the log's reference ids: {len(self.poses)} poses, {len(self.ids)} landmarks, "
                f"{self.sightings} sightings, chi2/dof {self.chi2_dof:.3f} (dof {self.dof}), {self.outliers} "
                f"sightings past chi2_2({OUTLIER_LEVEL})")


def reference_key(log: RangeBearingLog) -> str:
    """The cache key of a log's solution: the file's digest, the code that makes it, GTSAM's version."""
    code = files_digest(tuple(PACKAGE_ROOT / f for f in CODE), PACKAGE_ROOT)
    return digest({"log": log.digest, "code": code, "gtsam": importlib.metadata.version("gtsam")})


def reference_solution(log: RangeBearingLog, cache_dir: Path | None = None, use_cache: bool = True) -> ReferenceSolution:
    """The log's reference solution from the sequence cache (``<cache>/planar_log/<key>.npz``), else
    computed and stored."""
    from ...sim.cache import cached_sequence, load_fields, save_fields

    key = reference_key(log)
    if use_cache and (key, cache_dir) in _SOLVED:   # read once per process
        return _SOLVED[key, cache_dir]
    solution = cached_sequence(CACHE_FOLDER, key, lambda: announced(log), save_fields, load_fields, cache_dir,
                               use_cache, what="reference solution")
    _SOLVED[key, cache_dir] = solution
    return solution


_SOLVED: dict[tuple[str, Path | None], ReferenceSolution] = {}


def announced(log: RangeBearingLog) -> ReferenceSolution:
    """``solve(log)``, saying on stderr that it runs (once per log file) and how well it fits."""
    print(f"assocbench: computing the reference solution of {log.name} (once per log file) ...", file=sys.stderr,
          flush=True)
    solution = solve(log)
    print(f"assocbench: reference solution of {log.name}: {solution.describe()}", file=sys.stderr, flush=True)
    return solution


def solve(log: RangeBearingLog) -> ReferenceSolution:
    """Fit the log's poses and reference landmarks (module docstring); needs gtsam (the track says
    so before any run: ``Requirements``)."""
    import gtsam
    graph = _Graph(gtsam, log)
    isam = gtsam.ISAM2(gtsam.ISAM2Params())
    for start in range(0, len(log.pose_ids), BATCH):
        isam.update(*graph.batch(start, min(start + BATCH, len(log.pose_ids)), isam))
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph.full, isam.calculateEstimate(), gtsam.LevenbergMarquardtParams())
    values = optimizer.optimize()
    return graph.solution(values, optimizer.iterations())


class _Graph:
    """The factor graph of a log, built a batch of poses at a time (``solve``)."""

    def __init__(self, gtsam, log: RangeBearingLog) -> None:
        self.g, self.log = gtsam, log
        self.full = gtsam.NonlinearFactorGraph()
        z, R = log.range_bearing()
        swap = np.array([1, 0])
        self.z, self.R = z, R[:, swap][:, :, swap]   # GTSAM's order: bearing, range
        self.referenced = np.flatnonzero(log.sighting_ref >= 0)
        self.sightings_of = np.split(self.referenced, np.searchsorted(log.sighting_pose[self.referenced],
                                                                      np.arange(1, len(log.pose_ids))))
        self.ids: list[int] = []
        self.measured: list[tuple[int, int]] = []   # (factor index in full, sighting) of each bearing-range factor

    def batch(self, first: int, stop: int, isam) -> tuple:
        """The factors and initial values of poses ``first..stop−1`` and their sightings."""
        g, log = self.g, self.log
        graph, values = g.NonlinearFactorGraph(), g.Values()
        if first == 0:
            graph.add(g.PriorFactorPose2(g.symbol("x", 0), g.Pose2(0.0, 0.0, 0.0),
                                         g.noiseModel.Isotropic.Sigma(3, GAUGE_SIGMA)))
            pose = g.Pose2(0.0, 0.0, 0.0)
        else:
            pose = isam.calculateEstimate().atPose2(g.symbol("x", first - 1))
        known = set(self.ids)
        for n in range(first, stop):
            if n > 0:
                inc = g.Pose2(*log.increments[n - 1])
                graph.add(g.BetweenFactorPose2(g.symbol("x", n - 1), g.symbol("x", n), inc,
                                               g.noiseModel.Gaussian.Covariance(log.increment_covariances[n - 1])))
                pose = pose.compose(inc)
            values.insert(g.symbol("x", n), pose)
            for s in self.sightings_of[n]:
                ref = int(log.sighting_ref[s])
                if ref not in known:
                    known.add(ref)
                    self.ids.append(ref)
                    values.insert(g.symbol("l", ref), pose.transformFrom(g.Point2(*log.sighting_xy[s])))
                self.measured.append((self.full.size() + graph.size(), int(s)))
                graph.add(g.BearingRangeFactor2D(g.symbol("x", n), g.symbol("l", ref), g.Rot2(float(self.z[s, 1])),
                                                 float(self.z[s, 0]), g.noiseModel.Gaussian.Covariance(self.R[s])))
        for k in range(graph.size()):
            self.full.add(graph.at(k))
        return graph, values

    def solution(self, values, iterations: int) -> ReferenceSolution:
        g, full = self.g, self.full
        poses = np.array([[p.x(), p.y(), p.theta()] for p in
                          (values.atPose2(g.symbol("x", n)) for n in range(len(self.log.pose_ids)))])
        landmarks = np.array([values.atPoint2(g.symbol("l", r)) for r in self.ids], dtype=float).reshape(-1, 2)
        chi2 = 2.0 * full.error(values)
        measured = sum(full.at(k).dim() for k in range(full.size()))
        dof = measured - values.dim()   # the prior's 3 dimensions are the gauge's, not measurements
        gate = chi2_dist.ppf(OUTLIER_LEVEL, 2)
        outliers = sum(2.0 * full.at(k).error(values) > gate for k, _ in self.measured)
        return ReferenceSolution(poses, np.array(self.ids, dtype=np.int64), landmarks, float(chi2), int(dof),
                                 int(outliers), len(self.measured), int(iterations))
