"""The learned model as plain data: a boosted ensemble of regression trees in a JSON file, read
and evaluated with numpy and numba only (no scikit-learn, no pickle), so the shipped model loads in the
core install and on any library version.

The log-odds of a pair with features ``x`` is ``f(x) = base + Σ_t v_t(leaf_t(x))``, where each
tree sends ``x`` left at a node when ``float32(x[feature]) <= threshold`` (scikit-learn's trees
compare float32 features) and ``v_t`` already includes the learning rate."""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

import numpy as np
from numba import njit

from ...errors import UserError
from .features import FEATURE_VERSION, FEATURES

FORMAT = "assocbench-learned-associator"
# track -> model file in this folder (package data)
SHIPPED = {"camera": "camera.json", "planar": "planar.json", "lines": "lines.json"}


@dataclass(frozen=True)
class Forest:
    """A model file's content: trees as padded arrays (trees, nodes), ``-1`` children at leaves."""

    left: np.ndarray
    right: np.ndarray
    feature: np.ndarray
    threshold: np.ndarray
    value: np.ndarray
    depth: int
    base: float
    no_match: float        # log-odds a pair must beat to be paired (the validated no-match cost)
    track: str
    signature: tuple       # (d, angular dims) of the track's problems
    gate_confidence: float
    meta: dict             # training provenance: scenes, seeds, sizes, settings

    def log_odds(self, X: np.ndarray) -> np.ndarray:
        """``f(x)`` of each row of ``X`` (pairs, features)."""
        x = np.ascontiguousarray(X, dtype=np.float32).astype(np.float64)
        return _forest_log_odds(x, self.left, self.right, self.feature, self.threshold, self.value, self.base)


@njit(cache=True)
def _forest_log_odds(x, left, right, feature, threshold, value, base):
    """Each row's walk down every tree (pairs x trees x depth steps, no temporaries)."""
    out = np.full(x.shape[0], base)
    for r in range(x.shape[0]):
        for t in range(left.shape[0]):
            node = 0
            while left[t, node] >= 0:
                node = left[t, node] if x[r, feature[t, node]] <= threshold[t, node] else right[t, node]
            out[r] += value[t, node]
    return out


def forest_data(trees: list[dict], depth: int, base: float, no_match: float, track: str, signature: tuple,
                gate_confidence: float, meta: dict) -> dict:
    """The JSON document of a model (``trees``: per tree its ``left``, ``right``, ``feature``,
    ``threshold`` and ``value`` lists)."""
    return {"format": FORMAT, "feature_version": FEATURE_VERSION, "features": list(FEATURES), "track": track,
            "signature": {"d": signature[0], "angular": list(signature[1])}, "gate_confidence": gate_confidence,
            "depth": depth, "base": base, "no_match": no_match, "meta": meta, "trees": trees}


def parse_forest(doc: dict, where: str) -> Forest:
    """A ``Forest`` from a model document; a file of another format or feature version is refused."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise UserError(f"{where} is not a learned-associator model (no format {FORMAT!r}): make one with "
                        "`assocbench train --data DIR --out MODEL`")
    if doc.get("feature_version") != FEATURE_VERSION or doc.get("features") != list(FEATURES):
        raise UserError(f"model {where} was made for feature version {doc.get('feature_version')!r}, this "
                        f"assocbench computes version {FEATURE_VERSION}: retrain it with `assocbench train`")
    trees = doc["trees"]
    width = max(len(t["left"]) for t in trees)

    def padded(key: str, kind, fill) -> np.ndarray:
        out = np.full((len(trees), width), fill, dtype=kind)
        for k, t in enumerate(trees):
            out[k, :len(t[key])] = t[key]
        return out

    sig = doc["signature"]
    return Forest(padded("left", np.int64, -1), padded("right", np.int64, -1), padded("feature", np.int64, 0),
                  padded("threshold", np.float64, 0.0), padded("value", np.float64, 0.0), int(doc["depth"]),
                  float(doc["base"]), float(doc["no_match"]), str(doc["track"]),
                  (int(sig["d"]), tuple(int(a) for a in sig["angular"])), float(doc["gate_confidence"]),
                  dict(doc.get("meta") or {}))


def load_forest(path: str | Path) -> Forest:
    """The model in the JSON file ``path`` (one-line errors for a missing or unreadable file)."""
    try:
        doc = json.loads(Path(path).read_text())
    except OSError as exc:
        raise UserError(f"cannot read model {path}: {exc.strerror or exc}; pass params model=PATH of a file "
                        "`assocbench train` wrote") from None
    except ValueError:
        raise UserError(f"model {path} is not JSON: pass a file `assocbench train` wrote") from None
    return parse_forest(doc, str(path))


def shipped_path(track: str):
    """The package-data path of the model shipped for ``track``, or None."""
    name = SHIPPED.get(track)
    return files(__package__).joinpath(name) if name else None


def shipped_forests() -> dict[str, Forest]:
    """Every shipped model by track."""
    return {track: parse_forest(json.loads(shipped_path(track).read_text()), f"shipped {track} model")
            for track in SHIPPED}


def check_track(forest: Forest, track: str, where: str) -> None:
    """Refuse a model trained on another track than the run's."""
    if forest.track != track:
        raise UserError(f"model {where} was trained on the {forest.track} track; this run is on the {track} track: "
                        f"train one on a {track} export (`assocbench export`, then `assocbench train`)")
