"""The learned associator: trees as data that evaluate as scikit-learn does, training bit for bit,
the shipped model's training data disjoint from every leaderboard, and its one-line refusals."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from cli_errors import assert_one_line_error
from problems import random_problem

from assocbench.association.problem import Problem
from assocbench.associators.learned import forest as forest_module
from assocbench.associators.learned.associator import assign_log_odds
from assocbench.associators.learned.features import FEATURES, pair_features
from assocbench.associators.learned.forest import load_forest, parse_forest, shipped_path
from assocbench.cli.main import main
from assocbench.configs import shipped_config
from assocbench.errors import UserError
from assocbench.tracks.capabilities import OwnFrames, has
from assocbench.tracks.registry import iter_tracks

SHIPPED = json.loads(shipped_path("camera").read_text())
# every shipped model and the (d, angular dims) of its track's problems
SIGNATURES = {"camera": (2, ()), "planar": (2, (1,)), "lines": (2, (0,))}


def test_numpy_trees_give_scikit_learns_log_odds(rng):
    from sklearn import ensemble

    from assocbench.associators.learned.forest import forest_data
    from assocbench.associators.learned.train import TREES, _tree

    X = rng.normal(size=(600, len(FEATURES))) * rng.uniform(0.1, 100, len(FEATURES))
    y = (X[:, 0] + 0.01 * X[:, 3] ** 2 + rng.normal(size=600) > 0).astype(int)
    model = ensemble.GradientBoostingClassifier(**TREES).fit(X, y)
    doc = forest_data([_tree(e.tree_, TREES["learning_rate"]) for e in model.estimators_[:, 0]], TREES["max_depth"],
                      0.0, 0.0, "camera", (2, ()), 0.999, {})
    forest = parse_forest(json.loads(json.dumps(doc)), "test")
    X_new = rng.normal(size=(300, len(FEATURES))) * rng.uniform(0.1, 100, len(FEATURES))
    np.testing.assert_allclose(forest.log_odds(X_new), model.decision_function(X_new), rtol=0, atol=1e-9)


def test_features_are_finite_and_the_assignment_respects_the_no_match_cost(rng):
    p = random_problem(rng, n=8, m=10)
    feats, lms, X = pair_features(p)
    assert X.shape == (len(feats), len(FEATURES)) and np.all(np.isfinite(X))
    odds = np.linspace(-2, 2, len(feats))
    high = assign_log_odds(feats, lms, odds, 10.0, p.m, p.n)      # nothing beats a cost of 10
    assert np.all(high == -1)
    low = assign_log_odds(feats, lms, odds, -10.0, p.m, p.n)
    assert np.all(np.isin(low[low >= 0], feats)) and (low >= 0).sum() > 0


def leaderboard_scenes_and_seeds() -> tuple[set, set]:
    """Every scene (name or file stem) and seed of every shipped suite of every track."""
    scenes, seeds = set(), set()
    for track in iter_tracks():
        for entry in track.suites().values():
            raw = yaml.safe_load(entry.path.read_text())
            scenes |= {Path(s).stem for s in raw["scenes"]}
            seeds |= set(raw.get("seeds") or [0])
    return scenes, seeds


def test_every_track_with_problems_has_a_shipped_model():
    assert set(forest_module.SHIPPED) == set(SIGNATURES)
    simulated = {"camera", "planar", "lines", "dense"}   # the built-in tracks the models were trained on
    assert {t.name for t in iter_tracks() if t.name in simulated and not has(t, OwnFrames)} == set(SIGNATURES)


@pytest.mark.parametrize("track", sorted(SIGNATURES))
def test_the_shipped_model_never_saw_a_leaderboard_scene_or_seed(track):
    scenes, seeds = leaderboard_scenes_and_seeds()
    training = json.loads(shipped_path(track).read_text())["meta"]["training"]
    assert scenes and seeds and training["scenes"] and training["seeds"]
    assert not {Path(s).stem for s in training["scenes"]} & scenes
    assert not set(training["seeds"]) & seeds


def test_the_disjointness_check_sees_the_planar_and_lines_suites():
    """The scenes and seeds it compares against include the lidar tracks' leaderboards."""
    scenes, seeds = leaderboard_scenes_and_seeds()
    assert {"park", "post_grid", "colonnade", "office", "hallway", "furnished"} <= scenes and {0, 1} <= seeds


@pytest.mark.parametrize("track", sorted(SIGNATURES))
def test_the_shipped_model_loads_and_names_its_track_and_provenance(track):
    forest = load_forest(shipped_path(track))
    assert forest.track == track and forest.signature == SIGNATURES[track]
    doc = json.loads(shipped_path(track).read_text())
    assert doc["meta"]["fitted_with"]["features"] == list(FEATURES)
    assert doc["meta"]["training"]["suite"] == f"train_{track}.yaml"


def test_the_shipped_models_pick_themselves_by_the_problems_signature(rng):
    """Range-bearing problems (bearing wraps) get the planar model, (α, r) lines the lines model;
    the planar model pairs at least half the true pairs of a synthetic problem, nearly all of its pairs right
    (the synthetic prediction's σ 0.2 m is ten times the lidar's in its training, so it is cautious there)."""
    from assocbench import make_associator
    from assocbench.models.synthetic import range_bearing_problem

    learned = make_associator("learned")
    problem, truth = range_bearing_problem(rng, n=40)
    assert learned.forest_for(problem).track == "planar"
    out = learned.associate(problem)
    hits = int(np.sum((out >= 0) & (out == truth)))
    assert hits >= 0.5 * int(np.sum(truth >= 0)) and np.sum((out >= 0) & (out != truth)) <= 0.1 * hits
    lines = Problem(problem.z[:, ::-1].copy(), problem.R[:, ::-1, ::-1].copy(), problem.zhat[:, ::-1].copy(),
                    _swap_blocks(problem.P), volume=problem.volume, angular=(0,))
    assert learned.forest_for(lines).track == "lines"
    three = Problem(np.zeros((1, 3)), np.eye(3)[None], np.zeros((1, 3)), np.eye(3))
    with pytest.raises(ValueError, match="no shipped learned model for problems of dimension 3"):
        learned.associate(three)


def _swap_blocks(P: np.ndarray) -> np.ndarray:
    """The joint covariance with each landmark's two coordinates swapped."""
    order = np.arange(len(P)).reshape(-1, 2)[:, ::-1].ravel()
    return P[np.ix_(order, order)].copy()


def small_export(folder: Path, rng, seeds: int = 3) -> None:
    from assocbench.association.truth import FrameTruth
    from assocbench.dataset.writer import DatasetWriter

    with DatasetWriter(folder, {"generated_by": {"suite_file": "synthetic"}}) as w:
        for k in range(40):
            p = random_problem(rng, n=6, m=8)
            nis = np.linalg.norm(p.z[:6, None] - p.zhat[None], axis=2)
            assoc = np.where(nis.min(axis=0) < 3, nis.argmin(axis=0), -1)   # a labelling the features can learn
            for j in range(len(assoc)):   # one-to-one: a feature already taken pairs nothing more
                if assoc[j] in assoc[:j]:
                    assoc[j] = -1
            labels = np.full(p.m, -1)
            labels[assoc[assoc >= 0]] = p.landmark_ids[assoc >= 0]   # a truth that fits its problem
            w.add({"track": "camera", "scene": "synthetic", "difficulty": "d", "seed": k % seeds, "frame": k}, p,
                  FrameTruth(labels, assoc, assoc >= 0))


def test_training_is_reproducible_bit_for_bit_and_the_model_runs(tmp_path, rng):
    small_export(tmp_path / "data", rng)
    for name in ("a.json", "b.json"):
        assert main(["train", "--data", str(tmp_path / "data"), "--out", str(tmp_path / name)]) == 0
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()
    from assocbench import make_associator

    p = random_problem(rng, n=5, m=6)
    out = make_associator("learned", model=str(tmp_path / "a.json")).associate(p)
    assert out.shape == (5,)


def test_train_refuses_an_export_of_one_seed_and_a_folder_that_is_no_export(tmp_path, capsys, rng):
    small_export(tmp_path / "data", rng, seeds=1)
    out = str(tmp_path / "m.json")
    assert_one_line_error(capsys, main(["train", "--data", str(tmp_path / "data"), "--out", out]), "has one seed")
    assert_one_line_error(capsys, main(["train", "--data", str(tmp_path), "--out", out]), "not an assocbench export")
    assert_one_line_error(capsys, main(["train", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "m.txt")]),
                          "a model is a .json file")
    assert not (tmp_path / "m.json").exists()


def test_without_scikit_learn_train_says_how_to_install_it(tmp_path, capsys, monkeypatch, rng):
    small_export(tmp_path / "data", rng)
    monkeypatch.setitem(sys.modules, "sklearn", None)
    assert_one_line_error(capsys, main(["train", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "m.json")]),
                          "pip install 'assocbench[learn]'")
    assert not (tmp_path / "m.json").exists()


def test_a_model_of_another_feature_version_or_track_is_refused_in_one_line(tmp_path, capsys):
    old = dict(SHIPPED, feature_version=SHIPPED["feature_version"] - 1)
    (tmp_path / "old.json").write_text(json.dumps(old))
    args = ["run", "--scene", "room", "--frames", "2", "--method", "learned", "--out", str(tmp_path / "r")]
    assert_one_line_error(capsys, main([*args, "--set", f"params.model={tmp_path / 'old.json'}"]),
                          "feature version", "retrain")
    planar = dict(SHIPPED, track="planar")
    (tmp_path / "planar.json").write_text(json.dumps(planar))
    assert_one_line_error(capsys, main([*args, "--set", f"params.model={tmp_path / 'planar.json'}"]),
                          "trained on the planar track", "on the camera track")
    (tmp_path / "junk.json").write_text("{")
    with pytest.raises(UserError, match="not JSON"):
        load_forest(tmp_path / "junk.json")
    assert not (tmp_path / "r").exists()


def test_a_track_without_a_shipped_model_is_refused_in_one_line(tmp_path, capsys, monkeypatch):
    from assocbench.associators.learned import associator

    monkeypatch.setattr(forest_module, "SHIPPED", {"camera": "camera.json"})
    associator._shipped.cache_clear()
    try:
        code = main(["run", "--scene", "park", "--frames", "2", "--method", "learned", "--out", str(tmp_path / "r")])
    finally:
        associator._shipped.cache_clear()
    assert_one_line_error(capsys, code, "no shipped model for the planar track", "--set params.model=PATH")


@pytest.mark.parametrize("scene,model,trained,run", [("park", "lines", "lines", "planar"),
                                                     ("hallway", "planar", "planar", "lines"),
                                                     ("park", "camera", "camera", "planar")])
def test_a_shipped_model_of_another_track_is_refused_in_one_line(tmp_path, capsys, scene, model, trained, run):
    args = ["run", "--scene", scene, "--frames", "2", "--method", "learned", "--out", str(tmp_path / "r"),
            "--set", f"params.model={shipped_path(model)}"]
    assert_one_line_error(capsys, main(args), f"trained on the {trained} track", f"on the {run} track")
    assert not (tmp_path / "r").exists()


def test_a_retrained_model_changes_the_package_digest_that_keys_stored_results(tmp_path, monkeypatch):
    from assocbench import fingerprint

    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "mod.py").write_text("x = 1\n")
    (tmp_path / "pkg" / "model.json").write_text('{"trees": [1]}')
    monkeypatch.setattr(fingerprint, "PACKAGE_ROOT", tmp_path / "pkg")
    before = fingerprint.package_digest()
    (tmp_path / "pkg" / "model.json").write_text('{"trees": [2, 3]}')
    assert fingerprint.package_digest() != before


CORE_ONLY = """
import sys
sys.modules["sklearn"] = None   # as if neither were installed: importing one raises ImportError
sys.modules["pyarrow"] = None
import numpy as np
from assocbench import make_associator
from assocbench.tracks.camera.synthetic import camera_problem
problem, truth = camera_problem(np.random.default_rng(0), n=30)
out = make_associator("learned").associate(problem)
print(int(np.sum((out >= 0) & (out == truth))), int(np.sum(truth >= 0)))
"""


def test_the_shipped_model_runs_without_scikit_learn_or_pyarrow():
    import subprocess

    out = subprocess.run([sys.executable, "-c", CORE_ONLY], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    hits, true = map(int, out.stdout.split()[-2:])
    assert true > 0 and hits >= 0.8 * true   # it associates, not merely returns


@pytest.mark.parametrize("track", ["camera", "planar", "lines"])
def test_every_tracks_committed_leaderboard_has_a_learned_row_in_every_scenario(track):
    """The learned method is in each track's leaderboard suite and ranked in every scenario of
    the committed leaderboard (results/ for the camera, results/<track>/ otherwise)."""
    import pandas as pd

    suite, folder = ("leaderboard", "") if track == "camera" else (track, track)
    raw = yaml.safe_load(shipped_config(f"{suite}.yaml").read_text())
    assert "learned" in [m if isinstance(m, str) else m.get("name") for m in raw["methods"]]
    table = pd.read_csv(Path(__file__).parents[2] / "results" / folder / "leaderboard.csv")
    learned = table[table["method"] == "learned"]
    assert set(learned["scenario"]) == set(table["scenario"]) and len(learned) == table["scenario"].nunique()
    assert (learned["status"] == "ok").all()


def _tampered(tmp_path: Path, edit) -> Path:
    """The shipped camera model with ``edit(tree 0)`` applied, written to ``tmp_path``."""
    doc = json.loads(json.dumps(SHIPPED))
    edit(doc["trees"][0])
    path = tmp_path / "tampered.json"
    path.write_text(json.dumps(doc))
    return path


def _split(tree: dict) -> int:
    """The first node of ``tree`` that is a split (its root)."""
    return next(i for i, left in enumerate(tree["left"]) if left >= 0)


@pytest.mark.parametrize("edit,message", [
    (lambda t: t["feature"].__setitem__(_split(t), len(FEATURES)), "node 0: feature 12 is outside 0..11"),
    (lambda t: t["feature"].__setitem__(_split(t), -5), "node 0: feature -5 is outside 0..11"),
    (lambda t: t["right"].pop(), "has node lists of lengths"),
    (lambda t: t["left"].__setitem__(_split(t), 1_000_000), "node 0: children 1000000, "),
    (lambda t: t["left"].__setitem__(2, 0), "node 2: children 0, "),
    (lambda t: t["value"].__setitem__(3, None), "node 3: value must be a finite number, got None"),
])
def test_a_model_the_walk_cannot_follow_is_refused_when_loaded(tmp_path, capsys, edit, message):
    """Reproduction: the shipped camera model with tree 0's root splitting on feature 12 (of 12) or
    -5, or its right list one shorter than its left, ran with status ok (numba read past the
    features: recall 0.7557 / 1.0); a child 1e6 segfaulted the worker. Refused in one line naming
    the file, tree and node, before any frame."""
    path = _tampered(tmp_path, edit)
    with pytest.raises(UserError, match=f"^model {path}: tree 0 {message}"):
        load_forest(path)
    args = ["run", "--scene", "room", "--frames", "2", "--method", "learned", "--out", str(tmp_path / "r"),
            "--set", f"params.model={path}"]
    assert_one_line_error(capsys, main(args), str(path), "tree 0")
    assert not (tmp_path / "r").exists()
