"""Point-to-plane ICP (the homework's section 2): source points (world) against a depth frame.

**Estimate.** ``T = (R, t)⁻¹`` (world-to-camera) of the target frame, a source point ``p`` at
``p′ = T p``. Each iteration pairs points with pixels (a ``DenseAssociator``) and minimises the
linearised residuals

    r_i(δ) = A_i δ + b_i,   A_i = n_qᵀ [−[p′]ₓ | I] = [(p′ × n_q)ᵀ, n_qᵀ],   b_i = n_qᵀ (p′ − q)

over ``δ = (α, β, γ, t_x, t_y, t_z)`` (q, n_q: the pixel's vertex and normal):
``(Σ A_iᵀ A_i) δ = −Σ A_iᵀ b_i``, then ``T ← [δR | δt] T``, ``δR = exp([ω]ₓ)``.

**Iteration.** A trust region on the re-associated cost: the Levenberg–Marquardt step
(``solve_update``) is at most the radius, which never exceeds the gate's floor ``d_thr`` (pairs
within the gate say nothing about farther motion). At the trial pose the slope ``g₁ · δ`` decides: ≤
0 takes it (and may double the radius); > 0 overshot, so the pose goes to the secant's zero
``α = g₀·δ / (g₀·δ − g₁·δ)`` and the radius shrinks. Slopes, not costs: a re-associated pixel set's
cost carries that set's noise, the slope averages it out. Converged when a step is below
``converge_rot_deg``/``converge_trans`` or the radius below ``converge_trans``; a secant point
within ``SETTLE`` x ``converge_trans`` ends it (closer, re-association measures noise).

**Failure** (``failed=True`` with a ``reason``, never an exception for data): no valid pixel, too
few pairs at the guess, no convergence within ``max_iterations``, or at the final pose κ(S) >
``max_condition``, inlier share < ``min_inlier_share``, ``direction_share`` <
``min_direction_share``, gated residual rms > ``max_rms``, or a step from the guess beyond
``max_step_m`` / ``max_step_deg``. Each threshold and the benchmark behind it: ``IcpConfig``; the
capture range is bounded by the gate (``benchmarks/dense_icp_basin.py``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
from numba import njit
from scipy.linalg import solve_triangular

from ...associators.dense.base import DenseAssociator, Pairs, checked_inputs, checked_pairs, flat_maps
from ...errors import UserError
from ...models.depth_frame import NO_GEOM, DepthFrame
from .fused_ops import ZERO21, fma, outer_fma, symmetric6
from .settings import IcpConfig


@dataclass
class IcpResult:
    """``R, t``: the estimated camera-to-world pose (when ``failed``, the last estimate).
    ``converged``, ``failed`` / ``reason`` ("" when not failed), ``iterations`` (associations after
    the first), ``pairs`` at the returned pose and ``first_pairs`` at the guess, ``rms`` of
    ``pairs`` (m), ``inlier_share`` (``len(pairs) / pairs.considered``), ``condition`` κ(S),
    ``direction_share`` (NaN when not converged)."""

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
    associate_s: float = 0.0   # wall time spent in the associator's calls (a stage of the benchmark)
    direction_share: float = float("nan")


# Relative eigenvalue of S below which a motion is numerically unconstrained (rounding level of
# a sum of ~1e5 products): it gets no step at all, not a step of rounding noise over rounding noise.
NUMERICAL_RANK = 1e-12
# A rejected step shrinks the trust radius to this share of its length (Nocedal & Wright, alg. 4.1).
SHRINK = 0.25
# An overshot step whose secant point moves the points by less than this many converge_trans ends
# the iteration there, untried: at that scale the re-associated slope is the pair set's noise
# (module docstring, **Iteration**).
SETTLE = 3.0


@njit(cache=True)
def normal_equations_kernel(points, V, N, source, pixel, TR, Tt, floor, gate_a, gate_b):
    """(H, g, sse, sp, spp, sse_gated): ``H = Σ A_iᵀ A_i``, ``g = Σ A_iᵀ b_i``, ``sse = Σ b_i²``
    with ``A_i = [(p′ × n)ᵀ, nᵀ]``, ``b_i = n · (p′ − q)``, ``p′ = TR p + Tt``; ``sp = Σ p′``,
    ``spp = Σ |p′|²``; ``sse_gated = Σ (s_i b_i)²``,
    ``s_i = floor / max(floor, gate_a + gate_b d²)``. One pass, H in registers with ``fma`` (the
    same bits on any machine)."""
    h = ZERO21
    g0 = g1 = g2 = g3 = g4 = g5 = sse = sx = sy = sz = spp = ssg = 0.0
    for k in range(source.shape[0]):
        i, j = source[k], pixel[k]
        x = TR[0, 0] * points[i, 0] + TR[0, 1] * points[i, 1] + TR[0, 2] * points[i, 2] + Tt[0]
        y = TR[1, 0] * points[i, 0] + TR[1, 1] * points[i, 1] + TR[1, 2] * points[i, 2] + Tt[1]
        z = TR[2, 0] * points[i, 0] + TR[2, 1] * points[i, 1] + TR[2, 2] * points[i, 2] + Tt[2]
        nx, ny, nz = N[j, 0], N[j, 1], N[j, 2]
        b = nx * (x - V[j, 0]) + ny * (y - V[j, 1]) + nz * (z - V[j, 2])
        a0, a1, a2 = y * nz - z * ny, z * nx - x * nz, x * ny - y * nx
        h = outer_fma(h, a0, a1, a2, nx, ny, nz)
        g0 = fma(a0, b, g0); g1 = fma(a1, b, g1); g2 = fma(a2, b, g2)  # noqa: E702
        g3 = fma(nx, b, g3); g4 = fma(ny, b, g4); g5 = fma(nz, b, g5)  # noqa: E702
        sse = fma(b, b, sse)
        sx += x; sy += y; sz += z; spp += x * x + y * y + z * z  # noqa: E702
        gate = gate_a + gate_b * V[j, 2] * V[j, 2]
        if floor > 0.0 and gate > floor:   # s < 1; at the floor s = floor / floor = 1 exactly: no division
            s = floor / gate
            ssg += s * s * b * b
        else:
            ssg += b * b
    H = symmetric6(h)
    return H, np.array([g0, g1, g2, g3, g4, g5]), sse, np.array([sx, sy, sz]), spp, ssg


def gated_normal_equations(points: np.ndarray, frame: DepthFrame, pairs: Pairs, TR: np.ndarray, Tt: np.ndarray,
                           gate: tuple[float, float, float] = (0.0, 0.0, 0.0)):
    """``normal_equations_kernel`` of ``pairs`` at ``p′ = TR p + Tt``, ``gate`` the associator's
    ``gate_coefficients``."""
    _, V, N = flat_maps(frame)
    f64 = np.float64
    return normal_equations_kernel(np.ascontiguousarray(points, dtype=f64), V, N, pairs.source, pairs.pixel,
                                   np.ascontiguousarray(TR, dtype=f64), np.ascontiguousarray(Tt, dtype=f64),
                                   *(float(c) for c in gate))


def normal_equations(points: np.ndarray, frame: DepthFrame, pairs: Pairs, TR: np.ndarray, Tt: np.ndarray):
    """``(Σ A_iᵀ A_i, Σ A_iᵀ b_i, Σ b_i², Σ p′, Σ |p′|²)`` of ``pairs`` at ``p′ = TR p + Tt``."""
    return gated_normal_equations(points, frame, pairs, TR, Tt)[:5]


def rodrigues(w: np.ndarray) -> np.ndarray:
    """``exp([w]ₓ) = I + sin θ/θ [w]ₓ + (1 − cos θ)/θ² [w]ₓ²``, θ = |w| (series below 1e-8)."""
    th = float(np.linalg.norm(w))
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if th < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + np.sin(th) / th * K + (1 - np.cos(th)) / th ** 2 * K @ K


def stability_transform(sp: np.ndarray, spp: float, k: int) -> np.ndarray:
    """``T = diag(I/L, I) [[I, −[c]ₓ], [0, I]]``: the motion as a rotation about the pairs' centroid
    ``c = Σp′/k`` times their rms radius ``L = √(Σ|p′|²/k − |c|²)``, so every parameter moves the
    points by metres and ``T H Tᵀ`` compares them (Gelfand et al. 2003)."""
    c = sp / k
    L = np.sqrt(max(spp / k - c @ c, 1e-12))
    T = np.eye(6)
    T[:3, 3:] = -np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    T[:3] /= L
    return T


def damping(ev: np.ndarray, r: np.ndarray, radius: float) -> float:
    """The Levenberg–Marquardt ``λ ≥ 0`` with ``|y(λ)| ≈ radius``, ``y_i(λ) = r_i / (ev_i + λ)``, 0
    when the Gauss–Newton step fits: Newton on ``φ(λ) = 1/|y(λ)| − 1/radius`` (Moré & Sorensen
    1983), monotone from below."""
    lam = 0.0
    for _ in range(50):
        d = ev + lam
        norm = float(np.sqrt(np.sum((r / d) ** 2)))
        if norm <= radius * (1 + 1e-3) and (lam == 0.0 or norm >= radius * (1 - 1e-3)):
            return lam
        slope = float(np.sum(r * r / d ** 3)) / norm ** 3              # φ′(λ) > 0
        lam = max(lam - (1.0 / norm - 1.0 / radius) / slope, 0.0)
    return lam


def solve_update(H: np.ndarray, g: np.ndarray, T: np.ndarray, radius: float = np.inf) -> tuple[np.ndarray, float]:
    """(δ, κ): ``(S + λI) y = −T g``, ``δ = Tᵀ y``, ``S = T H Tᵀ``, κ = λ_max/λ_min of S; λ = 0
    (Gauss–Newton) when ``|y| ≤ radius``, else ``|y| = radius`` (``damping``). A direction below
    ``NUMERICAL_RANK · λ_max`` gets no step; damping, unlike truncation, still moves weakly
    constrained motions."""
    S, rhs = T @ H @ T.T, -T @ g
    ev, vec = np.linalg.eigh(S)
    cond = float(ev[-1] / ev[0]) if ev[0] > 0 else float("inf")
    if not ev[-1] > 0:
        return np.zeros(6), cond
    keep = ev > NUMERICAL_RANK * ev[-1]
    ev, r = ev[keep], vec[:, keep].T @ rhs
    y = vec[:, keep] @ (r / (ev + damping(ev, r, radius)))
    return T.T @ y, cond


def condition_number(H: np.ndarray, T: np.ndarray) -> float:
    """κ(S) = λ_max/λ_min of ``S = T H Tᵀ`` (inf when singular)."""
    ev = np.linalg.eigvalsh(T @ H @ T.T)
    return float(ev[-1] / ev[0]) if ev[0] > 0 else float("inf")


@njit(cache=True, inline="always")
def _add_outer(H, a0, a1, a2, a3, a4, a5, c):
    """``H += c a aᵀ`` (upper triangle; ``a`` = (a0..a5))."""
    a = (a0, a1, a2, a3, a4, a5)
    for r in range(6):
        for q in range(r, 6):
            H[r, q] += c * a[r] * a[q]


@njit(cache=True)
def information_kernel(points, normals, paired, TR, Tt, f, cx, cy, width, height, depth, floor, gate_a, gate_b):
    """(H_V, H_P), each ``Σ a_i a_iᵀ`` with ``a_i = [(p′ × n′)ᵀ, n′ᵀ]``, ``n′ = TR n`` the point's
    own normal: H_V over the visible points (in the image and not behind their pixel's depth by more
    than ``gate(d) = max(floor, gate_a + gate_b d²)``), H_P over the paired ones, ``paired[i]``
    times each."""
    shared, alone = ZERO21, ZERO21
    HV, HP = np.zeros((6, 6)), np.zeros((6, 6))
    for i in range(points.shape[0]):
        x = TR[0, 0] * points[i, 0] + TR[0, 1] * points[i, 1] + TR[0, 2] * points[i, 2] + Tt[0]
        y = TR[1, 0] * points[i, 0] + TR[1, 1] * points[i, 1] + TR[1, 2] * points[i, 2] + Tt[1]
        z = TR[2, 0] * points[i, 0] + TR[2, 1] * points[i, 1] + TR[2, 2] * points[i, 2] + Tt[2]
        seen = z > 0.0
        if seen:
            u, v = f * x / z + cx, f * y / z + cy
            seen = -0.5 <= u <= width - 0.5 and -0.5 <= v <= height - 0.5
            if seen:   # the nearest pixel (the image's last column or row at exactly W - ½, H - ½)
                d = depth[min(int(np.floor(v + 0.5)), height - 1) * width + min(int(np.floor(u + 0.5)), width - 1)]
                seen = not (d > 0.0 and z > d + max(floor, gate_a + gate_b * d * d))   # NaN depth: not hidden
        c = paired[i]
        if not seen and c == 0:
            continue
        nx = TR[0, 0] * normals[i, 0] + TR[0, 1] * normals[i, 1] + TR[0, 2] * normals[i, 2]
        ny = TR[1, 0] * normals[i, 0] + TR[1, 1] * normals[i, 1] + TR[1, 2] * normals[i, 2]
        nz = TR[2, 0] * normals[i, 0] + TR[2, 1] * normals[i, 1] + TR[2, 2] * normals[i, 2]
        a0, a1, a2 = y * nz - z * ny, z * nx - x * nz, x * ny - y * nx
        if seen and c == 1:
            shared = outer_fma(shared, a0, a1, a2, nx, ny, nz)
        elif seen and c == 0:
            alone = outer_fma(alone, a0, a1, a2, nx, ny, nz)
        else:
            if seen:
                _add_outer(HV, a0, a1, a2, nx, ny, nz, 1.0)
            _add_outer(HP, a0, a1, a2, nx, ny, nz, float(c))
    S, A = symmetric6(shared), symmetric6(alone)
    for r in range(6):
        for q in range(r, 6):   # the rare sums hold the upper triangles; each matrix made symmetric
            HV[r, q] = HV[q, r] = HV[r, q] + S[r, q] + A[r, q]
            HP[r, q] = HP[q, r] = HP[r, q] + S[r, q]
    return HV, HP


def source_information(points: np.ndarray, normals: np.ndarray, pairs: Pairs, frame: DepthFrame, TR: np.ndarray,
                       Tt: np.ndarray, gate: tuple[float, float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(H_V, H_P)`` (``information_kernel``) of the source points visible in ``frame`` at
    ``(TR, Tt)`` and of the paired ones; ``gate``: ``DenseAssociator.gate_coefficients`` (None:
    nothing hidden)."""
    f64, K = np.float64, frame.K
    floor, gate_a, gate_b = (np.inf, 0.0, 0.0) if gate is None else (float(g) for g in gate)
    paired = np.bincount(pairs.source, minlength=len(points)) if len(pairs) else np.zeros(len(points), np.int64)
    return information_kernel(np.ascontiguousarray(points, dtype=f64), np.ascontiguousarray(normals, dtype=f64),
                              paired, np.ascontiguousarray(TR, dtype=f64), np.ascontiguousarray(Tt, dtype=f64),
                              float(K.f), float(K.cx), float(K.cy), K.width, K.height,
                              np.ascontiguousarray(frame.depth, dtype=f64).reshape(-1), floor, gate_a, gate_b)


def direction_share(points: np.ndarray, normals: np.ndarray, pairs: Pairs, frame: DepthFrame, TR: np.ndarray,
                    Tt: np.ndarray, gate: tuple[float, float, float] | None = None) -> float:
    """ρ = min over motions u of ``uᵀ H_P u / uᵀ H_V u`` = λ_min(L⁻¹ H_P L⁻ᵀ), ``H_V = L Lᵀ``: the
    pairs' share of the visible points' information in the motion they keep worst (Gelfand et al.
    2003). Unlike the inlier share it weighs points by what they constrain: keeping half the points
    but none that fix one motion gives ρ ≈ 0. 0 when H_V is singular."""
    H_view, H_pairs = source_information(points, normals, pairs, frame, TR, Tt, gate)
    try:
        L = np.linalg.cholesky(H_view)
    except np.linalg.LinAlgError:
        return 0.0
    X = solve_triangular(L, H_pairs, lower=True)
    return float(np.linalg.eigvalsh(solve_triangular(L, X.T, lower=True))[0])


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


@dataclass
class _Linearised:
    """The pairs at a pose and their system: ``H``, ``g``, rms, gated rms, ``T``."""

    TR: np.ndarray
    Tt: np.ndarray
    pairs: Pairs
    H: np.ndarray
    g: np.ndarray
    rms: float
    rms_gated: float
    T: np.ndarray

    @classmethod
    def at(cls, points, frame: DepthFrame, pairs: Pairs, TR: np.ndarray, Tt: np.ndarray,
           gate: tuple[float, float, float]) -> _Linearised:
        H, g, sse, sp, spp, ssg = gated_normal_equations(points, frame, pairs, TR, Tt, gate)
        k = max(len(pairs), 1)
        return cls(TR, Tt, pairs, H, g, float(np.sqrt(sse / k)), float(np.sqrt(ssg / k)),
                   stability_transform(sp, spp, k))

    def stepped(self, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The world-to-camera estimate after the update: ``[δR | δt] T``."""
        dR = rodrigues(delta[:3])
        return dR @ self.TR, dR @ self.Tt + delta[3:]


def icp(points: np.ndarray, normals: np.ndarray, frame: DepthFrame, associator: DenseAssociator,
        R0: np.ndarray, t0: np.ndarray, cfg: IcpConfig | None = None) -> IcpResult:
    """Camera-to-world pose of ``frame`` registering the world ``points``/``normals`` from the guess
    ``(R0, t0)``. Bad shapes are a ``UserError``, bad data ``failed=True``; ``cfg`` defaults when
    None."""
    cfg = cfg if cfg is not None else IcpConfig()
    points, normals, _, _ = checked_inputs(points, normals, frame, np.eye(3), np.zeros(3))
    R0, t0 = _check_pose(R0, t0)
    TR, Tt = R0.T.copy(), -R0.T @ t0
    valid = frame.valid.reshape(-1)   # one mask a call: ``valid`` is computed from the maps each time
    if not valid.any():
        return _result(TR, Tt, Pairs.empty(), None, "the frame has no valid pixel (no finite depth with a normal)")
    # the method's copies, which ICP then reads too (one copy of the maps in the caches, not two):
    # a write the method forces into them moves its own pose, never the
    # frame fusion merges, the truth scoring reads or the caller's source
    clock, shown = _Clock(), _as_the_method_sees_it(frame)
    given = _handed("points", points), _handed("normals", normals)
    pairs = clock.timed(_associated, associator, *given, shown, R0.copy(), t0.copy())
    pairs = checked_pairs(pairs, len(points), valid)
    if len(pairs) < cfg.min_pairs:    # the association ran: its time is a stage of the frame's
        res = _result(TR, Tt, pairs, None, f"too few pairs: {len(pairs)} < min_pairs {cfg.min_pairs} at the initial "
                      f"guess ({pairs.considered} source points considered)")
        return replace(res, associate_s=clock.seconds)
    coefficients = getattr(associator, "gate_coefficients", None)   # a duck-typed method may not say
    gate = (0.0, 0.0, 0.0) if coefficients is None else coefficients
    cur, first = _Linearised.at(given[0], shown, pairs, TR, Tt, gate), pairs

    def linearised_at(delta: np.ndarray) -> _Linearised:
        TRn, Ttn = cur.stepped(delta)
        pairs = checked_pairs(clock.timed(_associated, associator, *given, shown, *_pose(TRn, Ttn)),
                              len(points), valid)
        return _Linearised.at(given[0], shown, pairs, TRn, Ttn, gate)

    radius_max = float(associator.d_thr)
    radius, converged, step_deg, step_m, it = radius_max, False, float("nan"), float("nan"), 0
    while it < cfg.max_iterations:
        delta, _ = solve_update(cur.H, cur.g, cur.T, radius)
        size = float(np.linalg.norm(np.linalg.solve(cur.T.T, delta)))    # |y|: the points' rms motion (m)
        step_deg, step_m = float(np.degrees(np.linalg.norm(delta[:3]))), float(np.linalg.norm(delta[3:]))
        small = step_deg < cfg.converge_rot_deg and step_m < cfg.converge_trans
        if small or it + 1 == cfg.max_iterations:    # no trial: it could not move farther than this step
            TRn, Ttn = cur.stepped(delta)
            cur = replace(cur, TR=TRn, Tt=Ttn)
            converged, it = small, it + 1
            break
        trial, it = linearised_at(delta), it + 1
        slope0, slope1 = float(cur.g @ delta), float(trial.g @ delta)    # ½ dF/dα at α = 0 and 1
        if len(trial.pairs) < cfg.min_pairs:             # the step lost the pairs: a shorter one
            radius = SHRINK * size
        elif slope1 <= 0.0:                               # still descending at the full step: take it
            if size >= 0.99 * radius and slope1 < 0.5 * slope0:   # the minimum lies beyond 2 radii
                radius = min(radius_max, 2.0 * radius)
            cur = trial
        else:                                             # overshot: the minimum along δ lies inside
            alpha = slope0 / (slope0 - slope1)            # the secant's zero of the slope, in (0, 1)
            delta, radius = alpha * delta, alpha * size
            if radius < SETTLE * cfg.converge_trans:     # the minimum is within the pairs' noise of here
                TRn, Ttn = cur.stepped(delta)
                cur = replace(cur, TR=TRn, Tt=Ttn)
                step_deg, step_m = float(np.degrees(np.linalg.norm(delta[:3]))), float(np.linalg.norm(delta[3:]))
                converged = True
                break
            cur, it = linearised_at(delta), it + 1
        step_deg, step_m = float(np.degrees(np.linalg.norm(delta[:3]))), float(np.linalg.norm(delta[3:]))
        if radius < cfg.converge_trans:     # no step moving the points by more than this improves the fit
            converged = True
            break
    if not converged:
        res = _result(cur.TR, cur.Tt, cur.pairs, first, f"no convergence in {cfg.max_iterations} iterations "
                      f"(last update {step_deg:.3g} deg, {step_m:.3g} m)", cur, it)
        return replace(res, associate_s=clock.seconds)
    rho = direction_share(*given, cur.pairs, shown, cur.TR, cur.Tt, coefficients)   # hidden as the association judges
    res = _result(cur.TR, cur.Tt, cur.pairs, first, _judged(cur, cfg, R0, t0, rho), cur, it, converged=True)
    return replace(res, associate_s=clock.seconds, direction_share=rho)


def _as_the_method_sees_it(frame: DepthFrame) -> DepthFrame:
    """``frame`` as the method sees it: the measured maps as read-only copies (``_handed``: fusion
    and ICP use them after the method), the truth withheld (NaN and ``NO_GEOM`` broadcasts: a method
    must not be scored on what it was not given). Copies, not views: a view's ``base`` is the
    sensor's buffer, truth included."""
    def withheld(a: np.ndarray, fill: float) -> np.ndarray:
        return np.broadcast_to(np.asarray(fill, dtype=np.asarray(a).dtype), np.shape(a))

    return replace(frame, depth=_handed("depth", frame.depth), vertices=_handed("vertices", frame.vertices),
                   normals=_handed("frame normals", frame.normals), true_points=withheld(frame.true_points, np.nan),
                   geom=withheld(frame.geom, NO_GEOM), R=withheld(frame.R, np.nan), t=withheld(frame.t, np.nan))


_HANDED: dict[str, np.ndarray] = {}   # the work space of ``_handed``: one flat buffer a role, grown as needed


def _handed(role: str, a: np.ndarray) -> np.ndarray:
    """A read-only copy of ``a`` in this process's work space for ``role``, valid during the call it
    is handed in; a forced write changes only the copy. Reused to spare page faults."""
    a = np.asarray(a)
    buf = _HANDED.get(role)
    if buf is None or buf.dtype != a.dtype or buf.size < a.size:
        buf = _HANDED[role] = np.empty(max(a.size, 2 * (0 if buf is None else buf.size)), a.dtype)
    buf.flags.writeable = True      # the method may have set the flags of its last copy or their base
    out = buf[:a.size].reshape(a.shape)
    np.copyto(out, a)
    out.flags.writeable = False
    return out


def _associated(associator: DenseAssociator, *args) -> Pairs:
    """``associator.associate(*args)``; a read-only ``ValueError`` names the arrays handed
    read-only."""
    try:
        return associator.associate(*args)
    except ValueError as exc:
        if "read-only" not in str(exc):
            raise
        raise ValueError(f"{type(associator).__name__}.associate: {exc} (the frame's depth, vertices and normals and "
                         "the source points and normals a method is handed are read-only: copy one to change it)"
                         ) from exc


class _Clock:
    """Wall time summed over the calls it makes (the association's share of ICP)."""

    def __init__(self) -> None:
        self.seconds = 0.0

    def timed(self, fn, *args):
        start = time.perf_counter()
        try:
            return fn(*args)
        finally:
            self.seconds += time.perf_counter() - start


def _judged(cur: _Linearised, cfg: IcpConfig, R0: np.ndarray, t0: np.ndarray, rho: float) -> str:
    """The failure reason of a converged estimate ("" when accepted; ``rho``: its direction share)."""
    cond, pairs = condition_number(cur.H, cur.T), cur.pairs
    share, rms = _share(pairs), cur.rms_gated
    if not cond <= cfg.max_condition:
        return (f"degenerate geometry: condition number {cond:.3g} > max_condition "
                f"{cfg.max_condition:.3g} (some motion is unconstrained by the pairs)")
    if share < cfg.min_inlier_share:
        return (f"inlier share {share:.3f} < min_inlier_share {cfg.min_inlier_share} "
                f"({len(pairs)} of {pairs.considered} considered pairs kept)")
    if rho < cfg.min_direction_share:
        return (f"lost direction: the pairs keep {rho:.3f} of the information of the visible source points in the "
                f"motion they constrain worst < min_direction_share {cfg.min_direction_share} (a slide to where "
                f"the surfaces that fix that motion find no partner: a wrong minimum of self-similar geometry)")
    if rms > cfg.max_rms:
        return (f"residual rms {rms:.4f} m > max_rms {cfg.max_rms} m (each residual scaled by the association "
                f"gate's floor over its gate; plain rms {cur.rms:.4f} m)")
    moved_m, moved_deg = step_from(R0, t0, *_pose(cur.TR, cur.Tt))
    if moved_m > cfg.max_step_m or moved_deg > cfg.max_step_deg:
        return (f"the estimate moved {moved_m:.3f} m and turned {moved_deg:.2f} deg from the initial guess, "
                f"beyond max_step_m {cfg.max_step_m} / max_step_deg {cfg.max_step_deg} (ICP's capture "
                f"range: a wrong minimum is as likely there)")
    return ""


def _share(pairs: Pairs) -> float:
    return len(pairs) / pairs.considered if pairs.considered else 0.0


def _result(TR: np.ndarray, Tt: np.ndarray, pairs: Pairs, first: Pairs | None, reason: str,
            cur: _Linearised | None = None, iterations: int = 0, converged: bool = False) -> IcpResult:
    R, t = _pose(TR, Tt)
    rms = cur.rms if cur is not None else float("nan")
    cond = condition_number(cur.H, cur.T) if cur is not None else float("nan")
    return IcpResult(R, t, converged, bool(reason), reason, iterations, pairs, first if first is not None else pairs,
                     rms, _share(pairs) if cur is not None else float("nan"), cond)


def step_from(R0: np.ndarray, t0: np.ndarray, R: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """``|t − t0|`` (m) and the angle of ``R0ᵀ R`` (deg) between two camera-to-world poses."""
    cos = np.clip((np.trace(R0.T @ R) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.linalg.norm(t - t0)), float(np.degrees(np.arccos(cos)))
