"""How well a lines sequence's extraction found the walls. An extracted line is *on a wall* when its
label names a map line; a map line is *found* when an extracted line carries its label,
*extractable* when ``lines.min_points`` beams truly hit it.

    precision = Σ_k on-wall lines / Σ_k extracted lines
    recall    = Σ_k found map lines / Σ_k extractable map lines
    e = [wrap(α − α*), r − r*]   with (α*, r*) = h(true pose, true map line)
    NEES = eᵀ Σ⁻¹ e              (χ²₂ for a consistent Σ: mean 2)
"""

from __future__ import annotations

import numpy as np

from ...models.polar_line import predict
from ...models.range_bearing import wrap


def line_errors(seq) -> tuple[np.ndarray, np.ndarray]:
    """Errors ``e`` (n, 2) of every on-wall line against its true line from the true pose, and their
    NEES."""
    errors, nees = [], []
    for k in range(len(seq)):
        on = np.flatnonzero(seq.labels[k] >= 0)
        if not len(on):
            continue
        truth = predict(seq.poses[k], seq.lines[seq.labels[k][on]])
        e = seq.z[k][on] - truth
        e[:, 0] = wrap(e[:, 0])
        errors.append(e)
        nees.append(np.einsum("ni,ni->n", e, np.linalg.solve(seq.R[k][on], e[..., None])[..., 0]))
    if not errors:
        return np.zeros((0, 2)), np.zeros(0)
    return np.vstack(errors), np.concatenate(nees)


def extraction_scores(seq) -> dict[str, float]:
    """Precision, recall, RMS α error (deg), RMS r error (mm), mean NEES, and lines per frame (module docstring)."""
    extracted = sum(len(lab) for lab in seq.labels)
    on_wall = sum(int(np.sum(lab >= 0)) for lab in seq.labels)
    found = sum(len(np.intersect1d(lab[lab >= 0], np.flatnonzero(seq.visible[k]))) for k, lab in enumerate(seq.labels))
    extractable = int(np.sum(seq.visible))
    e, nees = line_errors(seq)
    nan = float("nan")
    return {"precision": on_wall / extracted if extracted else nan,
            "recall": found / extractable if extractable else nan,
            "alpha_rms_deg": float(np.rad2deg(np.sqrt(np.mean(e[:, 0] ** 2)))) if len(e) else nan,
            "r_rms_mm": float(1e3 * np.sqrt(np.mean(e[:, 1] ** 2))) if len(e) else nan,
            "nees": float(np.mean(nees)) if len(nees) else nan,
            "lines_per_frame": extracted / len(seq) if len(seq) else nan}
