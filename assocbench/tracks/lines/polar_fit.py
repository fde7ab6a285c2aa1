"""Weighted least-squares line fit to polar points, in closed form, with its first-order covariance
(lecture 24).

**Model.** ``(ρ_i, β_i)`` lies on ``(α, r)`` when ``ρ_i cos(β_i − α) = r``; the fit minimises
``S(α, r) = Σ w_i d_i²``, ``d_i = ρ_i cos(β_i − α) − r``, ``w_i = 1/σ_ρi²``.

**Closed form.** With ``x = ρ cos β``, ``y = ρ sin β`` and the weighted centroid,
``r = x̄ cos α + ȳ sin α`` and ``S(α) = ½(Sxx + Syy) + ½ den cos 2α + ½ num sin 2α`` with

    num = 2 Sxy  = Σ w ρ² sin 2β − 2 X Y / W
    den = Sxx − Syy = Σ w ρ² cos 2β − (X² − Y²) / W      (W = Σw, X = Σ w ρ cos β, Y = Σ w ρ sin β)

``½ atan2(num, den)`` is the direction of the largest scatter; the minimum is a quarter turn away,
``α = ½ atan2(num, den) + π/2``, ``S_min = ½(Sxx + Syy) − ½ √(num² + den²)``; then ``r ≥ 0`` and α
wrapped. Six sums suffice, so a segment's fit is O(1) from cumulative sums.

**Covariance** (first order, weights fixed). At the minimum ``g = ∇ₓS = 0``, so
``∂x/∂ρ = −H⁻¹ ∂g/∂ρ`` and ``Σ = H⁻¹ (B_ρ diag(σ_ρ²) B_ρᵀ + B_β diag(σ_β²) B_βᵀ) H⁻¹``. With
``c_i = cos(β_i − α)``, ``s_i = sin(β_i − α)``, ``a_i = ρ_i s_i``, halved:

    H/2       = [[Σ w (a² − d ρ c), −Σ w a], [−Σ w a, Σ w]]
    ∂g/∂ρ_i/2 = w_i (c_i a_i + d_i s_i, −c_i)
    ∂g/∂β_i/2 = w_i (d_i ρ_i c_i − a_i², a_i)

(the ``d`` terms vanish on noise-free data, where
``Σ → (Σ w G Gᵀ)⁻¹ (Σ w² σ_ρ² c² G Gᵀ) (Σ w G Gᵀ)⁻¹``, ``G_i = (a_i, −1)``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...errors import UserError
from ...models.range_bearing import wrap

N_SUMS = 6   # Σw, Σwρcosβ, Σwρsinβ, Σwρ²cos2β, Σwρ²sin2β, Σwρ²


def point_terms(rho: np.ndarray, beta: np.ndarray, w: np.ndarray | float) -> np.ndarray:
    """Per-point terms (n, 6) whose sums over a set of points give its fit (``line_from_sums``)."""
    w = np.broadcast_to(np.asarray(w, float), np.shape(rho))
    wr, wr2 = w * rho, w * rho * rho
    return np.column_stack([w, wr * np.cos(beta), wr * np.sin(beta), wr2 * np.cos(2 * beta),
                            wr2 * np.sin(2 * beta), wr2])


def line_from_sums(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closed-form ``(α, r)`` and ``S_min`` of sums ``s`` (..., 6): ``α = ½ atan2(num, den) + π/2``,
    ``r = (X cos α + Y sin α)/W``, ``r ≥ 0``."""
    W, X, Y, C2, S2, Q = np.moveaxis(np.asarray(s, float), -1, 0)
    num = S2 - 2 * X * Y / W
    den = C2 - (X * X - Y * Y) / W
    alpha = 0.5 * np.arctan2(num, den) + np.pi / 2
    r = (X * np.cos(alpha) + Y * np.sin(alpha)) / W
    alpha = wrap(np.where(r < 0, alpha + np.pi, alpha))
    cost = np.maximum(0.5 * (Q - (X * X + Y * Y) / W) - 0.5 * np.hypot(num, den), 0.0)
    return alpha, np.abs(r), cost


@njit(cache=True)
def _covariance_kernel(rho, beta, w, var_rho, var_beta, alpha, r, starts):
    """``group_fits`` as a compiled loop, also each group's RMS, largest |d| and range of
    ``a = ρ sin(β − α)``."""
    n, k = len(rho), len(starts)
    cov, d = np.empty((k, 2, 2)), np.empty(n)
    stats = np.empty((k, 4))   # rms, max |d|, min a, max a
    for g in range(k):
        lo, hi = starts[g], starts[g + 1] if g + 1 < k else n
        h11 = h12 = h22 = m11 = m12 = m22 = sq = worst = 0.0
        amin, amax = np.inf, -np.inf
        for i in range(lo, hi):
            c, s = np.cos(beta[i] - alpha[g]), np.sin(beta[i] - alpha[g])
            a = rho[i] * s
            di = rho[i] * c - r[g]
            d[i] = di
            wi = w[i]
            h11 += wi * (a * a - di * rho[i] * c)
            h12 -= wi * a
            h22 += wi
            b1, b2 = wi * (c * a + di * s), -wi * c                   # ∂g/∂ρ_i / 2
            e1, e2 = wi * (di * rho[i] * c - a * a), wi * a           # ∂g/∂β_i / 2
            m11 += var_rho[i] * b1 * b1 + var_beta[i] * e1 * e1
            m12 += var_rho[i] * b1 * b2 + var_beta[i] * e1 * e2
            m22 += var_rho[i] * b2 * b2 + var_beta[i] * e2 * e2
            sq += di * di
            worst = max(worst, abs(di))
            amin, amax = min(amin, a), max(amax, a)
        l11 = np.sqrt(max(h11, 1e-300))                               # H/2 = L Lᵀ
        l21 = h12 / l11
        l22 = np.sqrt(max(h22 - l21 * l21, 1e-300))
        i11, i22 = 1.0 / l11, 1.0 / l22
        i21 = -l21 * i11 * i22                                        # L⁻¹ = [[i11, 0], [i21, i22]]
        q11, q12, q22 = i11 * i11 + i21 * i21, i21 * i22, i22 * i22   # (H/2)⁻¹ = L⁻ᵀ L⁻¹
        t11, t12 = q11 * m11 + q12 * m12, q11 * m12 + q12 * m22       # (H/2)⁻¹ M
        t21, t22 = q12 * m11 + q22 * m12, q12 * m12 + q22 * m22
        cov[g, 0, 0] = t11 * q11 + t12 * q12
        cov[g, 0, 1] = cov[g, 1, 0] = 0.5 * (t11 * q12 + t12 * q22 + t21 * q11 + t22 * q12)
        cov[g, 1, 1] = t21 * q12 + t22 * q22
        stats[g, 0], stats[g, 1] = np.sqrt(sq / max(hi - lo, 1)), worst
        stats[g, 2], stats[g, 3] = amin, amax
    return cov, d, stats


def group_fits(rho: np.ndarray, beta: np.ndarray, w: np.ndarray | float, var_rho: np.ndarray | float,
               var_beta: np.ndarray | float, alpha: np.ndarray, r: np.ndarray,
               starts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Covariances (k, 2, 2) of k groups' fits ``(α, r)`` (groups stored one after another from
    ``starts``; ``Σ = H⁻¹ M H⁻¹``), the distances ``d`` (n,) and per group (k, 4): RMS, largest |d|,
    least and largest along-line coordinate. ``w``, ``var_rho``, ``var_beta``: per point or one for
    all."""
    def per_point(x):   # a writeable contiguous copy: a read-only view would compile a second signature
        return np.array(np.broadcast_to(np.asarray(x, float), np.shape(rho)), dtype=float, order="C")
    return _covariance_kernel(per_point(rho), per_point(beta), per_point(w), per_point(var_rho), per_point(var_beta),
                              np.array(alpha, float), np.array(r, float), np.array(starts, np.int64))


def fit_polar_line(rho: np.ndarray, beta: np.ndarray, sigma_rho: np.ndarray | float,
                   sigma_beta: np.ndarray | float = 0.0) -> tuple[float, float, np.ndarray]:
    """Weighted least-squares line ``(α, r)`` through ``(ρ_i, β_i)`` (weights ``1/σ_ρi²``) and
    ``Σ_(α,r)`` from ``σ_ρ`` and ``σ_β`` (rad; 0: none), scalars or (n,). Bad input: UserError."""
    rho, beta = np.asarray(rho, float).ravel(), np.asarray(beta, float).ravel()
    if rho.shape != beta.shape:
        raise UserError(f"fit_polar_line: rho and beta must have one length, got {rho.shape[0]} and {beta.shape[0]}")
    sr = np.broadcast_to(np.asarray(sigma_rho, float), rho.shape)
    sb = np.broadcast_to(np.asarray(sigma_beta, float), rho.shape)
    if not (np.all(np.isfinite(sr)) and np.all(sr > 0)):
        raise UserError("fit_polar_line: sigma_rho must be finite and > 0 (it sets the weights 1/σ²)")
    if not (np.all(np.isfinite(sb)) and np.all(sb >= 0)):
        raise UserError("fit_polar_line: sigma_beta must be finite and >= 0")
    ok = np.isfinite(rho) & np.isfinite(beta)
    xy = rho[ok, None] * np.column_stack([np.cos(beta[ok]), np.sin(beta[ok])])
    if ok.sum() < 2 or np.ptp(xy, axis=0).max() <= 1e-12:
        raise UserError("fit_polar_line: a line needs at least 2 distinct finite points")
    rho, beta, sr, sb = rho[ok], beta[ok], sr[ok], sb[ok]
    w = 1.0 / sr ** 2
    alpha, r, _ = line_from_sums(point_terms(rho, beta, w).sum(axis=0))
    cov, _, _ = group_fits(rho, beta, w, sr ** 2, sb ** 2, np.atleast_1d(alpha), np.atleast_1d(r), np.zeros(1, int))
    return float(alpha), float(r), cov[0]
