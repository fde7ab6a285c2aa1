"""Point-to-plane ICP (the homework's section 2): source points (world) against a depth frame.

**Estimate.** ``T = (R, t)⁻¹`` (world-to-camera) of the target frame; a source point ``p`` is
``p′ = T p`` in the target camera. Each iteration pairs points with pixels (a ``DenseAssociator``
at the current guess) and minimises the linearised point-to-plane residuals

    r_i(δ) = A_i δ + b_i,   A_i = n_qᵀ [−[p′]ₓ | I] = [(p′ × n_q)ᵀ, n_qᵀ],   b_i = n_qᵀ (p′ − q)

over ``δ = (α, β, γ, t_x, t_y, t_z)`` (q, n_q: the pixel's vertex and normal, camera frame), i.e.
the normal equations ``(Σ A_iᵀ A_i) δ = −Σ A_iᵀ b_i`` (the homework's stacked ``A δ = −b`` in
least squares), then left-multiplies ``T ← [δR | δt] T`` with ``δR = exp([ω]ₓ)`` (exact Rodrigues).

**Solve.** The 6x6 normal matrix and right-hand side are summed in one compiled pass over the
pairs (27 products per pair, streaming: the n x 6 matrix A is never stored, so the pass reads only
the inputs; 0.6 ms for 60 000 pairs, where a QR of the stacked n x 6 A would first write 2.9 MB).
The matrix is symmetric positive definite whenever the pose is constrained, so it is solved by
Cholesky (``scipy.linalg.cho_factor``), after re-expressing the motion so that its parameters
are comparable (``stability_transform``: rotation about the pairs' centroid, scaled by their rms
radius): ``S = T H Tᵀ``. Cholesky squares the condition of A, which is harmless here: κ(S)
measured 4.7-6.5 on the synthetic room (noise-free and noisy) at the true pose (~1 digit lost),
and it is only used up to κ(S) = 1e4 (``SOLVE_CONDITION``, 4 of 16 digits).

**Failure** (``failed=True`` with a ``reason``, never an exception for data): no valid pixel, too
few pairs in an iteration, no convergence within ``max_iterations``, and on the last iteration a
degenerate normal matrix (κ(S) > ``max_condition``), an inlier share below ``min_inlier_share``
or a residual rms above ``max_rms``. An ill-conditioned EARLY iteration is not a failure: past
κ(S) = 1e4 its step is taken only along the constrained motions (``solve_update``).
Frame-to-frame and frame-to-model tracking are this call with a different source set.

**Capture range.** The association's distance gate bounds it: a start must put most points
within ``d_thr`` of their surface. At 2-3 m a 3 deg error moves points by 10-16 cm; with the
default 5 cm gate 4 of 8 such starts (projective) end at a wrong minimum, reported failed, and
with a 10 cm gate all 8 converge (tests/test_icp.py). On the crates scene from the identity
(``benchmarks/dense_icp_basin.py``, 6 seeds, sensor noise) frame pairs up to ~5 deg apart
register within about a millimetre, 8-11 deg apart mostly fail, and 11 deg apart always do.

**Thresholds** (``IcpConfig`` defaults). From ``benchmarks/dense_icp_thresholds.py`` (ICP from
starts 0-45 deg / 0-45 cm off, on the synthetic room with and without its crate and a single wall)
and from the crates pairs above:

* κ(S): ≤ 6.5 on the synthetic room at the true pose and ≥ 3 650 wherever it converged elsewhere,
  but the crates scene measures up to 520 at the true pose (noise-free; ≤ 310 with noise), and
  its noise-free wrong minima 2 800-14 000: ``max_condition = 1000``. A noisy wrong minimum can
  sit at κ 380-950, so κ alone does not separate them there.
* inlier share: ≥ 0.96 at the true pose between crates frames, 0.48-0.76 at most of their wrong
  minima; but frame-to-model tracking on bays runs at 0.6-0.75 (map points hidden from the
  current view count as considered), so ``min_inlier_share = 0.5`` only catches gross failure.
* residual rms at the true pose: ≤ 0.73 mm noise-free, ≤ 11 mm with the sensor's noise on
  crates; ``max_rms = 0.02`` m catches gross mismatch only (a wrong minimum fits its remaining
  pairs about as well).
* step from the guess: ``max_step_m = 0.15`` / ``max_step_deg = 10``, 5-10x a tracking step
  (1-3 cm, 0.2-1 deg a frame on the dense paths): of the crates pairs that converged to a wrong
  pose, it rejects those that slid farther (4 of 9 with noise); 3 wrong poses (15-18 cm off after
  a 6-10 cm slide) remain accepted, which the benchmark reports.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.linalg import LinAlgError, cho_factor, cho_solve

from ...associators.dense.base import DenseAssociator, Pairs, checked_inputs, flat_maps
from ...errors import UserError
from ...models.depth_frame import DepthFrame
from ...validation import in_range, validate_fields


@dataclass(frozen=True)
class IcpConfig:
    """Settings of ``icp`` (the ``icp:`` section of a run config).

    max_iterations: iterations at most; no convergence by then is a failure.
    converge_rot_deg / converge_trans: converged when one update rotates less than this (deg)
        and moves less than this (m).
    min_pairs: fewer pairs in any iteration is a failure (too little to constrain 6 dof).
    min_inlier_share: final pairs / considered (``Pairs.considered``) below this is a failure.
    max_rms: final point-to-plane residual rms (m) above this is a failure.
    max_condition: κ(S) (the normal matrix in comparable units, ``stability_transform``) of the
        last iteration above this is a failure: some motion is unconstrained (a single plane, a
        corridor's axis).
    max_step_m / max_step_deg: an estimate whose camera moved farther than this (m) or turned
        more than this (deg) from the initial guess is a failure: beyond ICP's capture range a
        converged pose is as likely a wrong minimum (one period of self-similar geometry off)
        as the right one.

    The thresholds' defaults and their evidence: see the module docstring.
    """

    max_iterations: int = field(default=100, metadata=in_range(1, 10_000))
    converge_rot_deg: float = field(default=5e-3, metadata=in_range(0, 180, lo_open=True))
    converge_trans: float = field(default=1e-4, metadata=in_range(0, None, lo_open=True))
    min_pairs: int = field(default=200, metadata=in_range(6, None))
    min_inlier_share: float = field(default=0.5, metadata=in_range(0, 1))
    max_rms: float = field(default=0.02, metadata=in_range(0, None, lo_open=True))
    max_condition: float = field(default=1000.0, metadata=in_range(1, None))
    max_step_m: float = field(default=0.15, metadata=in_range(0, None, lo_open=True))
    max_step_deg: float = field(default=10.0, metadata=in_range(0, 180, lo_open=True))

    def __post_init__(self) -> None:
        self.check()

    def check(self) -> None:
        """One-line ``UserError`` naming ``icp.<field>`` for a bad value."""
        validate_fields(self, "icp")


@dataclass
class IcpResult:
    """``R, t``: the estimated camera-to-world pose of the target frame (when ``failed``, the last
    estimate: do not trust it). ``converged``: the last update was below the convergence
    thresholds. ``failed`` / ``reason``: see the module docstring (``reason`` is "" when not
    failed). ``iterations``: updates applied. ``pairs``: the last iteration's association;
    ``first_pairs``: the first (at the initial guess). ``rms``: point-to-plane residual rms (m) of
    the last pairs; ``inlier_share``: ``len(pairs) / pairs.considered``; ``condition``: κ(S) of
    the last iteration's normal matrix (``solve_update``)."""

    R: np.ndarray
    t: np.ndarray
    converged: bool
    failed: bool
    reason: str
    iterations: int
    pairs: Pairs
    first_pairs: Pairs
    rms: float
    inlier_share: float
    condition: float


# κ(S) above which a step is truncated to the constrained motions. Far above IcpConfig.max_condition
# on purpose: truncating at 100 froze directions that were weak but real, and ICP then stopped at
# wrong minima with κ just above 100 (110 measured); solved fully up to 1e4, its wrong minima
# measured κ ≥ 3 650, far from the ≤ 6.5 of the right ones.
SOLVE_CONDITION = 1e4


@njit(cache=True)
def normal_equations_kernel(points, V, N, source, pixel, TR, Tt):
    """(H, g, sse, sp, spp): ``H = Σ A_iᵀ A_i`` (6, 6), ``g = Σ A_iᵀ b_i`` (6,), ``sse = Σ b_i²``
    with ``A_i = [(p′ × n)ᵀ, nᵀ]``, ``b_i = n · (p′ − q)``, ``p′ = TR p + Tt``; ``sp = Σ p′`` (3,)
    and ``spp = Σ |p′|²`` for the stability measure. One pass; scalar accumulators for the 21
    distinct entries so they stay in registers."""
    h00 = h01 = h02 = h03 = h04 = h05 = h11 = h12 = h13 = h14 = h15 = 0.0
    h22 = h23 = h24 = h25 = h33 = h34 = h35 = h44 = h45 = h55 = 0.0
    g0 = g1 = g2 = g3 = g4 = g5 = sse = sx = sy = sz = spp = 0.0
    for k in range(source.shape[0]):
        i, j = source[k], pixel[k]
        x = TR[0, 0] * points[i, 0] + TR[0, 1] * points[i, 1] + TR[0, 2] * points[i, 2] + Tt[0]
        y = TR[1, 0] * points[i, 0] + TR[1, 1] * points[i, 1] + TR[1, 2] * points[i, 2] + Tt[1]
        z = TR[2, 0] * points[i, 0] + TR[2, 1] * points[i, 1] + TR[2, 2] * points[i, 2] + Tt[2]
        nx, ny, nz = N[j, 0], N[j, 1], N[j, 2]
        b = nx * (x - V[j, 0]) + ny * (y - V[j, 1]) + nz * (z - V[j, 2])
        a0, a1, a2 = y * nz - z * ny, z * nx - x * nz, x * ny - y * nx
        h00 += a0 * a0; h01 += a0 * a1; h02 += a0 * a2; h03 += a0 * nx; h04 += a0 * ny; h05 += a0 * nz  # noqa: E702
        h11 += a1 * a1; h12 += a1 * a2; h13 += a1 * nx; h14 += a1 * ny; h15 += a1 * nz  # noqa: E702
        h22 += a2 * a2; h23 += a2 * nx; h24 += a2 * ny; h25 += a2 * nz  # noqa: E702
        h33 += nx * nx; h34 += nx * ny; h35 += nx * nz; h44 += ny * ny; h45 += ny * nz; h55 += nz * nz  # noqa: E702
        g0 += a0 * b; g1 += a1 * b; g2 += a2 * b; g3 += nx * b; g4 += ny * b; g5 += nz * b  # noqa: E702
        sse += b * b
        sx += x; sy += y; sz += z; spp += x * x + y * y + z * z  # noqa: E702
    H = np.array([[h00, h01, h02, h03, h04, h05], [h01, h11, h12, h13, h14, h15], [h02, h12, h22, h23, h24, h25],
                  [h03, h13, h23, h33, h34, h35], [h04, h14, h24, h34, h44, h45], [h05, h15, h25, h35, h45, h55]])
    return H, np.array([g0, g1, g2, g3, g4, g5]), sse, np.array([sx, sy, sz]), spp


def normal_equations(points: np.ndarray, frame: DepthFrame, pairs: Pairs, TR: np.ndarray, Tt: np.ndarray):
    """``(Σ A_iᵀ A_i, Σ A_iᵀ b_i, Σ b_i², Σ p′, Σ |p′|²)`` of ``pairs`` under the world-to-camera
    estimate ``p′ = TR p + Tt`` (see the module docstring)."""
    _, V, N = flat_maps(frame)
    f64 = np.float64
    return normal_equations_kernel(np.ascontiguousarray(points, dtype=f64), V, N, pairs.source, pairs.pixel,
                                   np.ascontiguousarray(TR, dtype=f64), np.ascontiguousarray(Tt, dtype=f64))


def rodrigues(w: np.ndarray) -> np.ndarray:
    """``exp([w]ₓ) = I + sin θ/θ [w]ₓ + (1 − cos θ)/θ² [w]ₓ²``, θ = |w| (series below 1e-8)."""
    th = float(np.linalg.norm(w))
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if th < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + np.sin(th) / th * K + (1 - np.cos(th)) / th ** 2 * K @ K


def stability_transform(sp: np.ndarray, spp: float, k: int) -> np.ndarray:
    """``T = diag(I/L, I) [[I, −[c]ₓ], [0, I]]`` (6, 6): the motion parameters re-expressed as a
    rotation about the pairs' centroid ``c = Σp′/k`` with its angle times their rms radius
    ``L = √(Σ|p′|²/k − |c|²)``, so that every parameter moves the points by metres and ``T H Tᵀ``
    compares them (Gelfand et al. 2003, "Geometrically stable sampling for the ICP algorithm")."""
    c = sp / k
    L = np.sqrt(max(spp / k - c @ c, 1e-12))
    T = np.eye(6)
    T[:3, 3:] = -np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    T[:3] /= L
    return T


def solve_update(H: np.ndarray, g: np.ndarray, T: np.ndarray, max_condition: float = SOLVE_CONDITION
                 ) -> tuple[np.ndarray, float]:
    """(δ, κ) for ``H δ = −g``: with ``S = T H Tᵀ`` (``stability_transform``) and ``δ = Tᵀ y``,
    ``S y = −T g``; κ = λ_max/λ_min of S (inf when singular). When ``κ ≤ max_condition``, y by
    Cholesky of S (at most log10 κ ≤ 4 of the 16 digits lost); otherwise only in the span of the
    eigenvectors of S with ``λ ≥ λ_max / max_condition``, leaving the (numerically) unconstrained
    motions unchanged: an early iteration, whose few pairs at a poor guess may lie on one plane,
    still moves the constrained ones; whether the problem is degenerate is judged on the last
    iteration (``IcpConfig.max_condition``)."""
    S, rhs = T @ H @ T.T, -T @ g
    ev, vec = np.linalg.eigh(S)
    cond = float(ev[-1] / ev[0]) if ev[0] > 0 else float("inf")
    if cond <= max_condition:
        try:
            return T.T @ cho_solve(cho_factor(S, lower=True, check_finite=False), rhs, check_finite=False), cond
        except LinAlgError:  # not positive definite after all (rounding): the truncated step below
            pass
    if not ev[-1] > 0:
        return np.zeros(6), cond
    keep = ev >= ev[-1] / max_condition
    return T.T @ (vec[:, keep] @ ((vec[:, keep].T @ rhs) / ev[keep])), cond


def _pose(TR: np.ndarray, Tt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera-to-world (R, t) of the world-to-camera estimate T."""
    return TR.T.copy(), -TR.T @ Tt


def _check_pose(R0, t0) -> tuple[np.ndarray, np.ndarray]:
    R0 = np.asarray(R0, dtype=np.float64)
    t0 = np.asarray(t0, dtype=np.float64).reshape(-1)
    if R0.shape != (3, 3) or t0.shape != (3,) or not (np.all(np.isfinite(R0)) and np.all(np.isfinite(t0))):
        raise UserError(f"the initial pose must be a finite R (3, 3) and t (3,), got {R0.shape} and {t0.shape}")
    if np.abs(R0.T @ R0 - np.eye(3)).max() > 1e-6 or np.linalg.det(R0) < 0:
        raise UserError("the initial rotation R0 is not a rotation matrix (RᵀR = I, det R = 1); orthonormalise it")
    return R0, t0


def icp(points: np.ndarray, normals: np.ndarray, frame: DepthFrame, associator: DenseAssociator,
        R0: np.ndarray, t0: np.ndarray, cfg: IcpConfig = IcpConfig()) -> IcpResult:
    """Camera-to-world pose of ``frame`` registering the source ``points``/``normals`` (world)
    to it, from the guess ``(R0, t0)``; see the module docstring. Bad shapes are a ``UserError``;
    bad data (nothing valid, degenerate, diverging) is ``failed=True`` with a ``reason``."""
    points, normals, _, _ = checked_inputs(points, normals, frame, np.eye(3), np.zeros(3))
    R0, t0 = _check_pose(R0, t0)
    TR, Tt = R0.T.copy(), -R0.T @ t0
    state = {"pairs": Pairs.empty(), "first": None, "rms": float("nan"), "share": float("nan"),
             "cond": float("nan"), "it": 0, "converged": False}

    def result(reason: str = "") -> IcpResult:
        R, t = _pose(TR, Tt)
        first = state["first"] if state["first"] is not None else state["pairs"]
        return IcpResult(R, t, state["converged"], bool(reason), reason, state["it"], state["pairs"], first,
                         state["rms"], state["share"], state["cond"])

    if not frame.valid.any():
        return result("the frame has no valid pixel (no finite depth with a normal)")
    step_deg = step_m = float("nan")
    for it in range(cfg.max_iterations):
        pairs = associator.associate(points, normals, frame, *_pose(TR, Tt))
        state.update(pairs=pairs, first=pairs if it == 0 else state["first"],
                     share=len(pairs) / pairs.considered if pairs.considered else 0.0)
        if len(pairs) < cfg.min_pairs:
            return result(f"too few pairs: {len(pairs)} < min_pairs {cfg.min_pairs} at iteration {it + 1} "
                          f"({pairs.considered} source points considered)")
        H, g, sse, sp, spp = normal_equations(points, frame, pairs, TR, Tt)
        delta, cond = solve_update(H, g, stability_transform(sp, spp, len(pairs)))
        state.update(rms=float(np.sqrt(sse / len(pairs))), cond=cond)
        dR = rodrigues(delta[:3])
        TR, Tt = dR @ TR, dR @ Tt + delta[3:]
        state["it"] = it + 1
        step_deg, step_m = float(np.degrees(np.linalg.norm(delta[:3]))), float(np.linalg.norm(delta[3:]))
        if step_deg < cfg.converge_rot_deg and step_m < cfg.converge_trans:
            state["converged"] = True
            break
    if not state["converged"]:
        return result(f"no convergence in {cfg.max_iterations} iterations (last update {step_deg:.3g} deg, "
                      f"{step_m:.3g} m)")
    if not state["cond"] <= cfg.max_condition:
        return result(f"degenerate geometry: condition number {state['cond']:.3g} > max_condition "
                      f"{cfg.max_condition:.3g} (some motion is unconstrained by the pairs)")
    if state["share"] < cfg.min_inlier_share:
        return result(f"inlier share {state['share']:.3f} < min_inlier_share {cfg.min_inlier_share} "
                      f"({len(state['pairs'])} of {state['pairs'].considered} considered pairs kept)")
    if state["rms"] > cfg.max_rms:
        return result(f"residual rms {state['rms']:.4f} m > max_rms {cfg.max_rms} m")
    moved_m, moved_deg = step_from(R0, t0, *_pose(TR, Tt))
    if moved_m > cfg.max_step_m or moved_deg > cfg.max_step_deg:
        return result(f"the estimate moved {moved_m:.3f} m and turned {moved_deg:.2f} deg from the initial guess, "
                      f"beyond max_step_m {cfg.max_step_m} / max_step_deg {cfg.max_step_deg} (ICP's capture "
                      f"range: a wrong minimum is as likely there)")
    return result()


def step_from(R0: np.ndarray, t0: np.ndarray, R: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """How far the camera moved from ``(R0, t0)`` to ``(R, t)`` (camera-to-world): ``|t − t0|`` (m)
    and the angle of ``R0ᵀ R`` (deg)."""
    cos = np.clip((np.trace(R0.T @ R) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.linalg.norm(t - t0)), float(np.degrees(np.arccos(cos)))
