"""The learned model as plain data: boosted regression trees in JSON, evaluated with numpy and numba
only (no scikit-learn, no pickle), so the shipped model loads in the core install on any library
version. A pair's log-odds is ``f(x) = base + Σ_t v_t(leaf_t(x))``, each tree sending ``x`` left
when ``float32(x[feature]) <= threshold`` (as scikit-learn compares) and ``v_t`` including the
learning rate."""

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
    trees = checked_trees(doc, where)
    try:
        sig = doc["signature"]
        return Forest(_padded(trees, "left", np.int64, -1), _padded(trees, "right", np.int64, -1),
                      _padded(trees, "feature", np.int64, 0), _padded(trees, "threshold", np.float64, 0.0),
                      _padded(trees, "value", np.float64, 0.0), int(doc["depth"]), float(doc["base"]),
                      float(doc["no_match"]), str(doc["track"]), (int(sig["d"]), tuple(int(a) for a in sig["angular"])),
                      float(doc["gate_confidence"]), dict(doc.get("meta") or {}))
    except (KeyError, TypeError, ValueError) as exc:   # a field missing or of another type
        raise UserError(f"model {where} lacks or mangles the field {exc}: make one with `assocbench train`") from None


def _padded(trees: list[dict], key: str, kind, fill) -> np.ndarray:
    """The trees' ``key`` lists as one (trees, longest tree) array, padded with ``fill``."""
    out = np.full((len(trees), max(len(t[key]) for t in trees)), fill, dtype=kind)
    for k, t in enumerate(trees):
        out[k, :len(t[key])] = t[key]
    return out


TREE_KEYS = ("left", "right", "feature", "threshold", "value")


def checked_trees(doc: dict, where: str) -> list[dict]:
    """The document's trees, each checked node by node (``_check_tree``); a model the walk cannot
    follow is refused in one line naming the file, tree and node, since the compiled walk indexes
    unchecked (out of range it would read other memory)."""
    trees = doc.get("trees")
    if not isinstance(trees, list) or not trees:
        raise UserError(f"model {where} has no trees: make one with `assocbench train --data DIR --out MODEL`")
    for k, tree in enumerate(trees):
        _check_tree(tree, f"model {where}: tree {k}")
    for key in ("base", "no_match", "gate_confidence"):
        if not isinstance(doc.get(key), (int, float)) or not np.isfinite(doc[key]):
            raise UserError(f"model {where}: {key} must be a finite number, got {_short(doc.get(key))}")
    return trees


def _check_tree(tree, where: str) -> None:
    """A tree's node lists: equal lengths; each node's children both -1 (a leaf) or both later nodes
    (every walk ends); split features in ``FEATURES``; finite thresholds and values."""
    if not isinstance(tree, dict) or not all(isinstance(tree.get(key), list) for key in TREE_KEYS):
        raise UserError(f"{where} is not a tree: it needs the lists {', '.join(TREE_KEYS)}")
    sizes = {key: len(tree[key]) for key in TREE_KEYS}
    if len(set(sizes.values())) != 1 or not sizes["left"]:
        raise UserError(f"{where} has node lists of lengths {sizes}: they must be one non-empty length")
    size = sizes["left"]
    for node in range(size):
        left, right, feature = (tree[key][node] for key in ("left", "right", "feature"))
        if not all(type(v) is int for v in (left, right, feature)):
            raise UserError(f"{where} node {node}: left, right and feature must be integers")
        leaf = left == -1 and right == -1
        if not leaf and not (node < left < size and node < right < size):
            raise UserError(f"{where} node {node}: children {left}, {right} must both be -1 (a leaf) or later "
                            f"nodes of the tree (below {size})")
        if not leaf and not 0 <= feature < len(FEATURES):
            raise UserError(f"{where} node {node}: feature {feature} is outside 0..{len(FEATURES) - 1}")
        for key in ("threshold", "value"):
            v = tree[key][node]
            if type(v) not in (int, float) or not np.isfinite(v):
                raise UserError(f"{where} node {node}: {key} must be a finite number, got {_short(v)}")


def _short(value) -> str:
    """``repr(value)`` cut to 40 characters, for a message."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


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
