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
The step is solved in the eigenbasis of ``S = T H Tᵀ``, after re-expressing the motion so that its
parameters are comparable (``stability_transform``: rotation about the pairs' centroid, scaled by
their rms radius, so ``|y|`` is about the points' rms motion in metres); κ(S) measured 4.7-6.5 on
the synthetic room at the true pose.

**Iteration** (``icp``): a trust region on the re-associated cost. Each step is the
Levenberg–Marquardt step (``solve_update``): the Gauss–Newton step when it moves the points by at
most the radius, else damped, ``(S + λI) y = −T g``, to exactly the radius (which starts at, and
never exceeds, the association gate's floor ``d_thr``: pairs found within the gate say nothing
about farther motion). A poorly conditioned step is thus taken, damped, never truncated: truncation
at κ 1e4 froze the weak motion of crates 0 -> 5 (κ 1.1e4) and stopped 45.8 mm off. The pairs are
then re-associated at the trial pose; the slope of the cost along the step there, ``g₁ · δ``,
decides: ≤ 0 (still descending) takes the trial (and doubles the radius when the minimum lies
beyond twice the step); > 0 means the step overshot the minimum of the re-associated cost, so the
pose goes to the secant's zero ``α = g₀·δ / (g₀·δ − g₁·δ)`` of the step and the radius shrinks to
that length. Slopes, not cost values, because the cost of a newly associated pixel set carries
that set's noise (0.3 % of the cost between neighbouring poses of noisy crates, more than a 20 mm
error in the weak direction changes it), while the slope averages it out. This stops the 2-cycle
(crates 0 -> 5 from the truth alternated between +1.19 and −0.36 mm forever) and the noisy
jitter: converged when a step is below ``converge_rot_deg``/``converge_trans`` (taken without a
trial association: it cannot move the pose farther; ``pairs`` are then those before it) or the
radius below ``converge_trans``; an overshot step whose secant point lies within ``SETTLE`` x
``converge_trans`` (0.3 mm of the points' rms motion) ends there without a further association:
re-associating at that scale measured the pair set's noise, not the cost (on 29 crates frames
frame-to-model, 7.4 associations a frame without this rule, 5.9 with it, the error to the true
pose median 0.37 / 0.36 mm, p90 0.97 / 0.96 mm). ``iterations`` counts the steps' associations (the
trials and the shortened steps) plus the last, untried step of a small-step or last-iteration exit
(a settled secant step is not counted: it associates nothing); the last allowed iteration is taken
untried.

**Failure** (``failed=True`` with a ``reason``, never an exception for data): no valid pixel, too
few pairs at the initial guess, no convergence within ``max_iterations``, and at the final pose a
degenerate normal matrix (κ(S) > ``max_condition``), an inlier share below ``min_inlier_share``,
a lost direction (``direction_share`` below ``min_direction_share``: the pairs keep too small a
share of the visible source points' information in some motion), a residual rms above
``max_rms`` (each residual scaled by the gate's floor over the gate that admitted it, so that
far, noisy pairs the depth-scaled gate lets in do not read as a mismatch: plain rms 30-35 mm on
bays from the identity) or a step from the guess beyond ``max_step_m`` / ``max_step_deg``. A
trial step that keeps fewer than ``min_pairs`` pairs is shortened, not failed.
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
  minima (measured with hidden points counted; ``considered`` now counts only visible source
  points, see ``associators.dense.base``), so ``min_inlier_share = 0.5`` only catches gross failure.
* direction share (``direction_share``, the pairs' share of the visible source points'
  information in the motion they keep worst; visible as the kdtree's inlier share counts
  them (the projective one also leaves out points on pixels without a measurement): a point
  hidden behind the measured surface by more than the gate can never pair, so it is neither a
  pair nor a loss. Counted, such points failed 25 frames of a crates view seen
  again, poses right to 1 mm, ρ 0.22-0.25: the model rendered into the view shows surfaces
  behind the near ones through the near surfaces' gaps and beside their edges (fusion leaves out
  a frame's pixels without a normal, at depth edges), 5 302 of 51 603 source points on the
  revisit against 1 474 of 44 780 the first time; ``benchmarks/dense_flat.py``). On the 40-frame leaderboard runs
  (projective, bays and crates, seeds 0 and 1, frame-to-model and frame-to-frame): 0.52-0.90 on
  every step that registered on crates and 0.68-0.80 on bays, and 0.057-0.076 on the four bays
  steps that slid sideways (34-57 mm off the true step; 0.035-0.059 on such steps when hidden
  points were counted): ``min_direction_share = 0.25``. Not counting hidden points costs some of
  the test's margin, since a slide also moves points behind the surface: with the test off
  (``benchmarks/dense_direction_share.py``, bays seed 1 frame-to-model, each wrong step fused)
  the 8 wrong steps' ρ rose from 0.035-0.485 to 0.055-0.521 and 6 of them fall below 0.25
  instead of 7 (the step after the first slide, against a map fused at its wrong pose, 0.16 ->
  0.255); the first slides stay at 0.055-0.11. Bays is a corridor seen along its length; the
  constant-position guess is up to 57 mm / 2.3 deg off, which puts the side walls, the only
  surfaces that fix the sideways translation, beyond the 5 cm gate. The first steps correct the
  turn by pairing the piers' faces, and the correction carries the camera sideways (the GN step
  itself, not the damping: a smaller trust radius slides the same); there the walls stay
  unpaired, and the pose keeps 0.56-0.68 of the points at κ 12-20 and a gated rms of 16 mm, so no
  other test can see it.
* residual rms at the true pose: ≤ 0.73 mm noise-free, ≤ 11 mm with the sensor's noise on
  crates; ``max_rms = 0.02`` m catches gross mismatch only (a wrong minimum fits its remaining
  pairs about as well).
* step from the guess: ``max_step_m = 0.15`` / ``max_step_deg = 10``, 5-10x a tracking step
  (1-3 cm, 0.2-1 deg a frame on the dense paths): of the crates pairs that converged to a wrong
  pose, it rejects those that slid farther (4 of 9 with noise); 3 wrong poses (15-18 cm off after
  a 6-10 cm slide) remain accepted, which the benchmark reports.
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
    """``R, t``: the estimated camera-to-world pose of the target frame (when ``failed``, the last
    estimate: do not trust it). ``converged``: the last update was below the convergence
    thresholds. ``failed`` / ``reason``: see the module docstring (``reason`` is "" when not
    failed). ``iterations``: associations after the first (each a tried or a shortened step).
    ``pairs``: the association at the returned pose; ``first_pairs``: at the initial guess.
    ``rms``: point-to-plane residual rms (m) of ``pairs``; ``inlier_share``:
    ``len(pairs) / pairs.considered``; ``condition``: κ(S) of their normal matrix (``solve_update``);
    ``direction_share``: ``direction_share`` at the returned pose (NaN when ICP did not converge)."""

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
    """(H, g, sse, sp, spp, sse_gated): ``H = Σ A_iᵀ A_i`` (6, 6), ``g = Σ A_iᵀ b_i`` (6,),
    ``sse = Σ b_i²`` with ``A_i = [(p′ × n)ᵀ, nᵀ]``, ``b_i = n · (p′ − q)``, ``p′ = TR p + Tt``;
    ``sp = Σ p′`` (3,) and ``spp = Σ |p′|²`` for the stability measure; ``sse_gated = Σ (s_i b_i)²``
    with ``s_i = floor / max(floor, gate_a + gate_b d²)`` at the pixel's depth d (the residual in
    units of the association gate that admitted it, times its floor; 1 when floor is 0). One pass;
    the 21 distinct entries of H summed in registers (``outer_fma``), each product added with one
    rounding (``fma``: the same bits on any machine): 0.40 against 0.52 ms for 39 000 pairs."""
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
    """``(Σ A_iᵀ A_i, Σ A_iᵀ b_i, Σ b_i², Σ p′, Σ |p′|², Σ (s_i b_i)²)`` of ``pairs`` under the
    world-to-camera estimate ``p′ = TR p + Tt``; ``gate`` the associator's ``gate_coefficients``
    (``normal_equations_kernel``)."""
    _, V, N = flat_maps(frame)
    f64 = np.float64
    return normal_equations_kernel(np.ascontiguousarray(points, dtype=f64), V, N, pairs.source, pairs.pixel,
                                   np.ascontiguousarray(TR, dtype=f64), np.ascontiguousarray(Tt, dtype=f64),
                                   *(float(c) for c in gate))


def normal_equations(points: np.ndarray, frame: DepthFrame, pairs: Pairs, TR: np.ndarray, Tt: np.ndarray):
    """``(Σ A_iᵀ A_i, Σ A_iᵀ b_i, Σ b_i², Σ p′, Σ |p′|²)`` of ``pairs`` under the world-to-camera
    estimate ``p′ = TR p + Tt`` (the homework's stacked system; see the module docstring)."""
    return gated_normal_equations(points, frame, pairs, TR, Tt)[:5]


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
    compares them (Gelfand et al. 2003, "Geometrically stable sampling for the ICP algorithm").
    In these units ``y = T⁻ᵀ δ`` is (the rotation's displacement at radius L, the centroid's
    displacement), and ``|y|`` about the rms displacement of the points."""
    c = sp / k
    L = np.sqrt(max(spp / k - c @ c, 1e-12))
    T = np.eye(6)
    T[:3, 3:] = -np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    T[:3] /= L
    return T


def damping(ev: np.ndarray, r: np.ndarray, radius: float) -> float:
    """The Levenberg–Marquardt ``λ ≥ 0`` with ``|y(λ)| ≈ radius``, ``y_i(λ) = r_i / (ev_i + λ)``
    (the eigenbasis of S), or 0 when the Gauss–Newton step ``y(0)`` is inside the radius: Newton's
    method on ``φ(λ) = 1/|y(λ)| − 1/radius`` (Moré & Sorensen 1983), which is nearly linear in λ
    and approached from below, so it converges monotonically; a few iterations reach 1e-3."""
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
    """(δ, κ): the Levenberg–Marquardt step ``(S + λI) y = −T g``, ``δ = Tᵀ y``, with
    ``S = T H Tᵀ`` (``stability_transform``) and κ = λ_max/λ_min of S (inf when singular); λ = 0
    (the Gauss–Newton step, ``H δ = −g``) when ``|y| ≤ radius``, else the λ with ``|y| = radius``
    (``damping``): the minimiser of the linearised cost ``|A δ + b|²`` within the trust region.
    Solved in the eigenbasis of S, which also gives κ; a direction with eigenvalue below
    ``NUMERICAL_RANK · λ_max`` (numerically unconstrained: a single plane's sliding) gets no step.
    Unlike truncating the solve at a condition number, damping moves every constrained motion,
    however weakly constrained, by no more than the radius allows."""
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
    """(H_V, H_P), each ``Σ a_i a_iᵀ`` (6, 6) with ``a_i = [(p′ × n′)ᵀ, n′ᵀ]`` at ``p′ = TR p + Tt``
    and the point's OWN normal ``n′ = TR n`` (the information it would give if it were paired): H_V
    over the visible points (in view: ``z′ > 0``, ``−½ ≤ f x′/z′ + cx ≤ W − ½`` and likewise v,
    ``Intrinsics.in_image``; and not hidden: not farther than the measured depth ``d`` of their
    nearest pixel (``depth``, flat) by more than ``gate(d) = max(floor, gate_a + gate_b d²)``), H_P
    over the paired ones, each counted ``paired[i]`` times. One pass
    over the points. The common cases sum in registers (``outer_fma``): a point in view paired once
    adds to one sum both matrices share, one in view and unpaired to H_V's own; the rest (paired
    twice or out of view: a k-d tree's pairs) go to the matrices (0.51 against 0.72 ms for 45 000
    points, when both matrices took every point)."""
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
    """``(H_V, H_P)`` (``information_kernel``): the point-to-plane information of the source points
    visible in ``frame`` at the world-to-camera estimate ``(TR, Tt)``, and of the paired ones.
    ``gate``: the association's ``(floor, a, b)`` (``DenseAssociator.gate_coefficients``), whose
    ``gate(d)`` says how far behind the measured surface a point is hidden; None: none is."""
    f64, K = np.float64, frame.K
    floor, gate_a, gate_b = (np.inf, 0.0, 0.0) if gate is None else (float(g) for g in gate)
    paired = np.bincount(pairs.source, minlength=len(points)) if len(pairs) else np.zeros(len(points), np.int64)
    return information_kernel(np.ascontiguousarray(points, dtype=f64), np.ascontiguousarray(normals, dtype=f64),
                              paired, np.ascontiguousarray(TR, dtype=f64), np.ascontiguousarray(Tt, dtype=f64),
                              float(K.f), float(K.cx), float(K.cy), K.width, K.height,
                              np.ascontiguousarray(frame.depth, dtype=f64).reshape(-1), floor, gate_a, gate_b)


def direction_share(points: np.ndarray, normals: np.ndarray, pairs: Pairs, frame: DepthFrame, TR: np.ndarray,
                    Tt: np.ndarray, gate: tuple[float, float, float] | None = None) -> float:
    """ρ = min over motions u of ``uᵀ H_P u / uᵀ H_V u``, the smallest generalised eigenvalue of
    ``(H_P, H_V)`` (``source_information``: the paired source points and every visible source
    point, in front of the camera, projecting into the image and not hidden behind the measured
    surface by more than the association's ``gate``; a pixel without a depth hides nothing): the
    pairs' share of the information in the motion they keep worst. ``H_V = L Lᵀ`` (Cholesky), ρ = λ_min(L⁻¹ H_P L⁻ᵀ)
    by triangular solves; invariant to the motion's parametrisation. The plain inlier share counts
    points; ρ weighs them by what they constrain (Gelfand et al. 2003's stability analysis, applied
    to the pairs against the source): a pose that keeps half the points but none that fix one
    motion has ρ ≈ 0. 0 when the points in view constrain no motion at all (H_V singular)."""
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
    """The pairs at a pose and their point-to-plane system: ``H``, ``g``, the residual rms (m) and
    the rms of the residuals referred to the gate's floor (``gated_normal_equations``), ``T``
    (``stability_transform``)."""

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
    """Camera-to-world pose of ``frame`` registering the source ``points``/``normals`` (world)
    to it, from the guess ``(R0, t0)``; see the module docstring (**Iteration**). Bad shapes are a
    ``UserError``; bad data (nothing valid, degenerate, diverging) is ``failed=True`` with a ``reason``.
    ``cfg``: the ``icp`` settings (their defaults when None)."""
    cfg = cfg if cfg is not None else IcpConfig()
    points, normals, _, _ = checked_inputs(points, normals, frame, np.eye(3), np.zeros(3))
    R0, t0 = _check_pose(R0, t0)
    TR, Tt = R0.T.copy(), -R0.T @ t0
    valid = frame.valid.reshape(-1)   # one mask a call: ``valid`` is computed from the maps each time
    if not valid.any():
        return _result(TR, Tt, Pairs.empty(), None, "the frame has no valid pixel (no finite depth with a normal)")
    # the method's copies, which ICP then reads too (one copy of the maps in the caches, not two:
    # an ICP call 0.6-1.6 ms faster on crates): a write the method forces into them moves its own pose, never the
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
    """``frame`` as the method sees it: the measured maps (``depth``, ``vertices``, ``normals``) as
    read-only copies (``_handed``), since fusion merges the frame's own maps into the map
    after the method's calls and ICP solves on them; the truth (``true_points``, ``geom``, ``R``,
    ``t``) withheld, NaN and ``NO_GEOM`` of the same shapes (read-only broadcasts: no copy), since a
    method that read the true pose or the true points would be scored on what it was not given. A
    write is an error of the frame: a method setting each paired pixel's true point to its source
    point once raised crates' precision, 4 frames at one iteration, from 0.079 to 0.908 with the
    same pairs. Copies, not read-only views, as ``harness.runner.private_copy`` gives the feature
    tracks' methods: a view's ``base`` is the sensor's one buffer of every map, the truth included,
    and ``setflags(write=True)`` makes a view of a writable array writable again."""
    def withheld(a: np.ndarray, fill: float) -> np.ndarray:
        return np.broadcast_to(np.asarray(fill, dtype=np.asarray(a).dtype), np.shape(a))

    return replace(frame, depth=_handed("depth", frame.depth), vertices=_handed("vertices", frame.vertices),
                   normals=_handed("frame normals", frame.normals), true_points=withheld(frame.true_points, np.nan),
                   geom=withheld(frame.geom, NO_GEOM), R=withheld(frame.R, np.nan), t=withheld(frame.t, np.nan))


_HANDED: dict[str, np.ndarray] = {}   # the work space of ``_handed``: one flat buffer a role, grown as needed


def _handed(role: str, a: np.ndarray) -> np.ndarray:
    """A read-only C-contiguous copy of ``a`` in this process's work space for ``role``: a plain
    write is an error, and one forced through ``setflags``, ``base`` or ``ctypes`` changes only the
    copy. The copy is valid during the ICP call it was handed in (the next call writes over it; a
    method keeping a frame copies what it keeps). The work space is reused because fresh arrays
    cost their page faults: the maps of a 320x240 frame and 45 000 source points in 1.7 ms fresh,
    0.19 ms into the work space (2026-11-26, one core)."""
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
    """``associator.associate(*args)``; a ``ValueError`` about a read-only array says which arrays the
    method is handed read-only, since numpy's own words ("output array is read-only") name none."""
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
    """The failure reason of a converged estimate ("" when accepted; ``rho``: its
    ``direction_share``): module docstring, **Failure**."""
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
    """How far the camera moved from ``(R0, t0)`` to ``(R, t)`` (camera-to-world): ``|t − t0|`` (m)
    and the angle of ``R0ᵀ R`` (deg)."""
    cos = np.clip((np.trace(R0.T @ R) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.linalg.norm(t - t0)), float(np.degrees(np.arccos(cos)))
