"""Fit the learned associator from an export (``assocbench train``): scikit-learn's gradient
boosting on the pairs' features, written out as plain data (``forest``). The last seed's frames are
held out to pick the no-match cost ``τ`` from ``TAU_GRID`` (best micro F1, ties to the smaller |τ|);
the trees fit the other seeds. Deterministic (fixed ``random_state``, no subsampling, export order):
the same export gives the same file bit for bit."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from ...atomic import write_text
from ...dataset.reader import read_card, read_problems
from ...errors import UserError
from .associator import assign_log_odds
from .features import FEATURES, GATE_CONFIDENCE, pair_features
from .forest import forest_data, parse_forest

TREES = {"n_estimators": 120, "max_depth": 3, "learning_rate": 0.1, "subsample": 1.0, "init": "zero",
         "random_state": 0}
TAU_GRID = tuple(np.round(np.arange(-4.0, 4.01, 0.25), 2))


def sklearn_ensemble():
    """scikit-learn's ensemble module, or a one-line error saying how to install it."""
    try:
        from sklearn import ensemble
    except ImportError:
        raise UserError("assocbench train needs scikit-learn: pip install 'assocbench[learn]'") from None
    return ensemble


def frame_pairs(item) -> dict:
    """One frame's gated pairs, their features and labels (1: the true pair)."""
    feats, lms, X = pair_features(item.problem)
    label = (item.truth.association[lms] == feats).astype(np.int64)
    return {"feats": feats, "lms": lms, "X": X, "y": label, "truth": item.truth.association,
            "m": item.problem.m, "n": item.problem.n}


def read_pairs(folder: Path) -> tuple[list[dict], dict]:
    """Every frame's pairs and what the export holds (track, signature, scenes, seeds)."""
    frames, seen = [], {"tracks": set(), "signatures": set(), "scenes": set(), "seeds": set(), "difficulties": set()}
    for batch in read_problems(folder):
        for item in batch:
            frames.append({**frame_pairs(item), "seed": item.seed})
            for key, value in (("tracks", item.track), ("signatures", (item.problem.d, item.problem.angular)),
                               ("scenes", item.scene), ("seeds", item.seed), ("difficulties", item.difficulty)):
                seen[key].add(value)
    if len(seen["tracks"]) != 1 or len(seen["signatures"]) != 1:
        raise UserError(f"{folder} mixes tracks {sorted(seen['tracks'])}: a model learns one track's problems")
    if len(seen["seeds"]) < 2:
        raise UserError(f"{folder} has one seed: export a suite with two or more (the last validates the no-match cost)")
    return frames, seen


def micro_f1(frames: list[dict], tau: float) -> float:
    """Micro F1 of the assignment at no-match cost ``tau`` over ``frames`` (``log_odds`` set)."""
    tp = fp = fn = 0
    for f in frames:
        out = assign_log_odds(f["feats"], f["lms"], f["log_odds"], tau, f["m"], f["n"])
        got, true = out >= 0, f["truth"] >= 0
        hit = got & (out == f["truth"])
        tp, fp, fn = tp + int(hit.sum()), fp + int((got & ~hit).sum()), fn + int((true & ~hit).sum())
    return 2 * tp / max(2 * tp + fp + fn, 1)


def train_model(folder: Path) -> dict:
    """The model document fitted on the export in ``folder``."""
    card = read_card(folder)
    ensemble = sklearn_ensemble()
    frames, seen = read_pairs(folder)
    held = max(seen["seeds"])
    fit = [f for f in frames if f["seed"] != held]
    X, y = np.vstack([f["X"] for f in fit]), np.concatenate([f["y"] for f in fit])
    if len(np.unique(y)) < 2:
        raise UserError(f"{folder} has no true pair (or only true pairs) inside the gate: nothing to learn")
    model = ensemble.GradientBoostingClassifier(**TREES).fit(X, y)
    trees = [_tree(est.tree_, TREES["learning_rate"]) for est in model.estimators_[:, 0]]
    held_out = [f for f in frames if f["seed"] == held]
    sig = next(iter(seen["signatures"]))
    doc = forest_data(trees, TREES["max_depth"], 0.0, 0.0, next(iter(seen["tracks"])), sig, GATE_CONFIDENCE, {})
    forest = parse_forest(doc, "the model in training")
    for f in held_out:
        f["log_odds"] = forest.log_odds(f["X"])
    scores = [(micro_f1(held_out, tau), -abs(tau), tau) for tau in TAU_GRID]
    best_f1, _, tau = max(scores)
    doc["no_match"] = float(tau)
    doc["meta"] = _meta(folder, card, seen, held, fit, X, y, best_f1)
    return doc


def _tree(tree, rate: float) -> dict:
    """One scikit-learn regression tree as lists; leaf values times the learning rate."""
    return {"left": tree.children_left.tolist(), "right": tree.children_right.tolist(),
            "feature": np.maximum(tree.feature, 0).tolist(), "threshold": tree.threshold.tolist(),
            "value": (rate * tree.value[:, 0, 0]).tolist()}


def _meta(folder: Path, card: dict, seen: dict, held: int, fit: list, X, y, f1: float) -> dict:
    from sklearn import __version__ as sklearn_version

    data = (Path(folder) / "problems.parquet").read_bytes()
    return {"training": {"scenes": sorted(seen["scenes"]), "seeds": sorted(seen["seeds"]),
                         "difficulties": sorted(seen["difficulties"]), "suite": card["generated_by"].get("suite_file"),
                         "data_sha256": hashlib.sha256(data).hexdigest(), "frames_fitted": len(fit),
                         "pairs_fitted": int(len(y)), "true_pairs_fitted": int(y.sum()),
                         "validation_seed": int(held)},
            "fitted_with": {"scikit_learn": sklearn_version, "estimator": "GradientBoostingClassifier",
                            "params": TREES, "features": list(FEATURES)},
            "validation": {"no_match_grid": [float(t) for t in TAU_GRID], "micro_f1": round(float(f1), 6)}}


def write_model(doc: dict, out: Path) -> None:
    """The model as compact JSON (keys in a fixed order: the same fit gives the same bytes)."""
    write_text(out, json.dumps(doc, separators=(",", ":")) + "\n")
